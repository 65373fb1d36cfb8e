"""Ctrl-C and SIGTERM for a process that spins rclpy in its main thread (the suite runner).

Python raises KeyboardInterrupt at the next bytecode; if that is a Python callback which rclpy's C++
called (an executor's wait set, an event handler's ``__exit__``), pybind11 cannot pass it on and the
process ends in ``std::terminate`` ("Fatal Python error: Aborted", exit -6) with the MCAP unfinished.
``DeferredInterrupts`` holds a signal that arrives inside ``deferred()`` until that block ends (a
spin_once of at most its timeout) and raises KeyboardInterrupt there, in plain Python; anywhere else it
raises at once, as Python would.
"""

from __future__ import annotations

import signal
from collections.abc import Iterator
from contextlib import contextmanager


class DeferredInterrupts:
    """Signal handlers that raise KeyboardInterrupt, but never inside a ``deferred()`` block."""

    def __init__(self) -> None:
        self._depth = 0
        self.pending: int | None = None  # the signal held back, if any

    def install(self, signals=(signal.SIGINT, signal.SIGTERM)) -> None:
        """Handle ``signals`` here: KeyboardInterrupt at once, or at the end of a ``deferred()`` block."""
        for signum in signals:
            signal.signal(signum, self._handle)

    def _handle(self, signum, frame) -> None:
        if self._depth:
            self.pending = signum
            return
        raise KeyboardInterrupt

    @contextmanager
    def deferred(self) -> Iterator[None]:
        """Hold signals back for the block (keep it short: a spin_once); raise KeyboardInterrupt after it."""
        self._depth += 1
        try:
            yield
        finally:
            self._depth -= 1
            if not self._depth and self.pending is not None:
                self.pending = None
                raise KeyboardInterrupt


INTERRUPTS = DeferredInterrupts()
