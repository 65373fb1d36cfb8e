"""Sim-clock helpers (pure). ClockRate: how fast the simulation clock runs against the wall clock --
faster than real time (``real_time_factor`` > 1 or 0 = as fast as possible) a margin meant in wall time,
e.g. the time a command needs to reach the emulator, is that many more sim seconds. HeldFor: a
condition that must hold without a break for a stretch of sim time (a pose settled, estimates current).
StillFor: a pose that stays inside a small band for a stretch of sim time (a robot at rest)."""

from __future__ import annotations

import math
from collections import deque

import numpy as np

REAL_TIME_FACTOR_MAX = 100.0  # the emulator's real_time_factor parameter: sim seconds per wall second at most
# the slowest a run's sim clock may be set to (0 = as fast as possible aside): the runner's wall-time waits
# assume at least this rate
REAL_TIME_FACTOR_MIN = 0.05


class ClockRate:
    """d(sim)/d(wall) over the last ``window_s`` of wall time, from (wall, sim) samples in seconds: the
    median of the rates between consecutive samples, so a jump of the clock (the first /clock after 0,
    a skipped stretch) does not count.

    1.0 until the samples span ``min_span_s`` of wall time with at least ``min_intervals`` intervals; a
    clock that is not running (sim <= 0) is ignored, one that jumps back (a restarted simulation)
    starts over."""

    def __init__(self, window_s: float = 2.0, min_span_s: float = 0.3, min_intervals: int = 4):
        self.window_s, self.min_span_s, self.min_intervals = window_s, min_span_s, min_intervals
        self._samples: deque[tuple[float, float]] = deque()

    def add(self, wall: float, sim: float) -> None:
        """Add a sample at ``wall`` and ``sim`` (s); ignored while sim <= 0, a sim time going back starts over."""
        if sim <= 0.0:
            return
        if self._samples and sim < self._samples[-1][1]:
            self._samples.clear()
        self._samples.append((wall, sim))
        while wall - self._samples[0][0] > self.window_s:
            self._samples.popleft()

    def rate(self) -> float:
        """The current d(sim)/d(wall): the median of the recent rates, 1.0 until enough samples."""
        if len(self._samples) <= self.min_intervals or self._samples[-1][0] - self._samples[0][0] < self.min_span_s:
            return 1.0
        samples = np.array(self._samples)
        walls, sims = np.diff(samples[:, 0]), np.diff(samples[:, 1])
        keep = walls > 0
        return float(np.median(sims[keep] / walls[keep])) if keep.any() else 1.0

    def wall_margin(self, seconds: float, resolution: float = 0.01) -> float:
        """``seconds`` of wall time in sim seconds, rounded up to ``resolution`` (never less than
        ``seconds``: slower than real time the margin stays as configured)."""
        rate = self.rate()
        if rate <= 1.0:
            return seconds
        return math.ceil(seconds * rate / resolution - 1e-9) * resolution


class HeldFor:
    """True once a condition has held without a break for ``duration_s`` of sim time.

    Feed it ``update(holds, now)`` at every check; a check where it does not hold starts it over."""

    def __init__(self, duration_s: float):
        self.duration_s = float(duration_s)
        self.since: float | None = None  # sim time (s) since which it has held

    def update(self, holds: bool, now: float) -> bool:
        """Whether the condition, ``holds`` at sim time ``now`` (s), has held for duration_s."""
        if not holds:
            self.since = None
            return False
        if self.since is None:
            self.since = now
        return now - self.since >= self.duration_s


# a robot at rest on real hardware still moves by its sensors' noise through its servo loops (a fraction of a
# micrometre); "still" is a band around where it came to rest, not an unchanged reading
STILL_BAND_M = 1e-6
STILL_BAND_RAD = 1e-5


class StillFor:
    """True once a pose [x, y, z, roll, pitch, yaw] (m, rad) has stayed within ``band_m`` / ``band_rad`` of
    where it came to rest for ``duration_s`` of sim time; a pose outside the band restarts it from there."""

    def __init__(self, duration_s: float, band_m: float = STILL_BAND_M, band_rad: float = STILL_BAND_RAD):
        self.held = HeldFor(duration_s)
        self.band = np.array([band_m] * 3 + [band_rad] * 3)
        self.anchor: np.ndarray | None = None  # the pose it is holding at

    def update(self, pose, now: float) -> bool:
        """Whether ``pose`` (6,) at sim time ``now`` (s) completes duration_s within the band."""
        pose = np.asarray(pose, dtype=float)
        if self.anchor is None or np.any(np.abs(pose - self.anchor) > self.band):
            self.anchor = pose
            self.held.update(False, now)
        return self.held.update(True, now)
