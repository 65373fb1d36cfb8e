"""Replay timing without ROS: which messages, when (original log-time spacing / rate)."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass

from .reader import RawMessage


@dataclass(frozen=True)
class ReplayOptions:
    """rate > 0 scales time (2.0 = twice as fast); start_offset_s skips the run's first seconds."""

    rate: float = 1.0
    start_offset_s: float = 0.0
    include: tuple[str, ...] = ()
    exclude: tuple[str, ...] = ()

    def __post_init__(self):
        if not self.rate > 0:
            raise ValueError(f"rate must be > 0, got {self.rate}")
        if self.start_offset_s < 0:
            raise ValueError(f"start_offset_s must be >= 0, got {self.start_offset_s}")

    def wants(self, topic: str) -> bool:
        return (not self.include or topic in self.include) and topic not in self.exclude


def schedule(
    messages: Iterable[RawMessage], run_start_ns: int, opts: ReplayOptions
) -> Iterator[tuple[float, RawMessage]]:
    """(seconds after replay start, message) for the selected messages, in log-time order.

    Time zero of the replay is ``run_start_ns + start_offset_s``; a message at log
    time t is due at ``(t - t0) / rate`` seconds.
    """
    t0 = run_start_ns + round(opts.start_offset_s * 1e9)
    for msg in messages:
        if msg.log_time < t0 or not opts.wants(msg.topic):
            continue
        yield (msg.log_time - t0) / 1e9 / opts.rate, msg


class Pacer:
    """Waits until ``start + due`` on a monotonic clock: sleeps, then spins the last ``spin_s``."""

    def __init__(self, spin_s: float = 0.002, now: Callable[[], float] = time.perf_counter):
        self._spin_s = spin_s
        self._now = now
        self.start = now()

    def wait_until(self, due_s: float, stop: Callable[[], bool] = lambda: False) -> float:
        """Block until ``due_s`` after start (or ``stop()``); returns the lateness in s."""
        target = self.start + due_s
        while True:
            remaining = target - self._now()
            if remaining <= 0 or stop():
                return -remaining
            if remaining > self._spin_s:
                time.sleep(min(remaining - self._spin_s, 0.05))
