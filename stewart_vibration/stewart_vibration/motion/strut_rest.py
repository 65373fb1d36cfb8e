"""Whether the struts are at rest, judged from their measured lengths alone.

A move is planned from rest at the measured lengths; the robot departs from its own commanded state. While
the robot still moves on its own (its way home after an e-stop reset, an e-stop's braking) those differ by
the motion, and the robot refuses the move's first segment as too hard an acceleration. So a move waits
until the struts have stopped. The test compares the mean length of each strut over the last window with
the mean over the window before it: a vibration of the units (or strut jitter under it) averages out over a
window of several of its cycles, a drift does not.
"""

from __future__ import annotations

import numpy as np

REST_WINDOW_S = 0.1  # s of sim time per mean (3.5 cycles of the slowest vibration the planner takes, 35 Hz)
REST_SPEED_M_S = 2e-4  # a strut drifting slower than this is at rest (0.2 mm/s: a departure step far below
# strut_acceleration_max over a trajectory's first 20 ms sample)


class StrutRest:
    """Measured strut lengths in, ``at_rest()`` out (``observe`` them in stamp order)."""

    def __init__(self, window_s: float = REST_WINDOW_S, speed_m_s: float = REST_SPEED_M_S):
        self.window = float(window_s)
        self.speed_limit = float(speed_m_s)
        self._t = np.empty(0)
        self._lengths = np.empty((0, 6))

    def observe(self, stamps, lengths) -> None:
        """Strut lengths [n, 6] (m) measured at ``stamps`` [n] (s, the robot's clock); older than two windows
        are forgotten. A stamp earlier than the newest kept (the robot's clock restarted) starts afresh."""
        stamps = np.asarray(stamps, float)
        if not len(stamps):
            return
        if len(self._t) and stamps[0] < self._t[-1]:
            self.clear()
        t = np.concatenate([self._t, stamps])
        keep = t >= t[-1] - 2.0 * self.window
        self._t = t[keep]
        self._lengths = np.vstack([self._lengths, np.asarray(lengths, float)])[keep]

    def clear(self) -> None:
        """Forget every length (nothing known: not at rest)."""
        self._t, self._lengths = np.empty(0), np.empty((0, 6))

    def speed(self) -> float | None:
        """The fastest strut's drift (m/s): the change of its mean length from the previous window to the last,
        over the window; None until two windows of lengths are known."""
        if len(self._t) < 4 or self._t[-1] - self._t[0] < 1.9 * self.window:
            return None
        last = self._t > self._t[-1] - self.window
        before = ~last
        if not before.any():
            return None
        drift = self._lengths[last].mean(axis=0) - self._lengths[before].mean(axis=0)
        return float(np.abs(drift).max() / self.window)

    def at_rest(self) -> bool:
        """True when two windows of lengths are known and every strut drifts slower than the limit."""
        speed = self.speed()
        return speed is not None and speed < self.speed_limit
