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

    def start_ns(self, run_start_ns: int) -> int:
        """Run time at which the replay starts (the run's first message + start_offset_s)."""
        return run_start_ns + round(self.start_offset_s * 1e9)

    def wants(self, topic: str) -> bool:
        """True when ``topic`` is replayed: in ``include`` (or no include list) and not in ``exclude``."""
        return (not self.include or topic in self.include) and topic not in self.exclude


def schedule(
    messages: Iterable[RawMessage], run_start_ns: int, opts: ReplayOptions
) -> Iterator[tuple[float, RawMessage]]:
    """(seconds after replay start, message) for the selected messages, in log-time order.

    Time zero of the replay is ``run_start_ns + start_offset_s``; a message at log
    time t is due at ``(t - t0) / rate`` seconds.
    """
    t0 = opts.start_ns(run_start_ns)
    for msg in messages:
        if msg.log_time < t0 or not opts.wants(msg.topic):
            continue
        yield (msg.log_time - t0) / 1e9 / opts.rate, msg


@dataclass(frozen=True)
class ClockTick:
    """A /clock sample to publish: the run's time (ns) at this point of the replay."""

    clock_ns: int


def with_clock(
    items: Iterable[tuple[float, RawMessage]], t0_ns: int, opts: ReplayOptions, clock_rate_hz: float
) -> Iterator[tuple[float, RawMessage | ClockTick]]:
    """``items`` (from :func:`schedule`) with a ClockTick every ``1 / clock_rate_hz`` s of replay time.

    Tick k is due at k / clock_rate_hz s (wall, whatever the rate) and carries the run time
    t0 + k / clock_rate_hz * rate; ticks come before a message due at the same time and stop
    after the last message's due time (one final tick carries the last message's time).
    """
    if not clock_rate_hz > 0:
        raise ValueError(f"clock_rate_hz must be > 0, got {clock_rate_hz}")
    period = 1.0 / clock_rate_hz
    k = 0
    last_due = None
    for due, msg in items:
        while k * period <= due:
            yield k * period, ClockTick(t0_ns + round(k * period * opts.rate * 1e9))
            k += 1
        yield due, msg
        last_due = due
    if last_due is not None and (k - 1) * period < last_due:
        yield last_due, ClockTick(t0_ns + round(last_due * opts.rate * 1e9))


def recorded_rate_hz(log_times_ns: list[int]) -> float | None:
    """Mean rate of a recorded stream (count - 1 over its span), None with fewer than two samples."""
    if len(log_times_ns) < 2 or max(log_times_ns) <= min(log_times_ns):
        return None
    return (len(log_times_ns) - 1) / ((max(log_times_ns) - min(log_times_ns)) / 1e9)


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
