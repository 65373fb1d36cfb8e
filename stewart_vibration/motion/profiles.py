"""Minimum-jerk point-to-point motion (Flash and Hogan 1985), for strut lengths or any coordinates.

With s = t / T in [0, 1], x(t) = x0 + (x1 - x0) (10 s^3 - 15 s^4 + 6 s^5) (``splines.smoothstep``): zero
velocity and acceleration at both ends; peak speed 1.875 |x1 - x0| / T at s = 1/2, peak acceleration
5.7735 |x1 - x0| / T^2 at s = 0.5 -+ sqrt(3)/6.
"""

from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError
from ..splines import smoothstep

MIN_JERK_PEAK_SPEED = 1.875  # max of d/ds (10 s^3 - 15 s^4 + 6 s^5)


def minimum_jerk(start, goal, duration: float, times):
    """(positions, velocities, accelerations) [n, dim] of a minimum-jerk move.

    start, goal: [dim]; duration T (s) > 0; times [n] (s), clamped to [0, T].
    """
    if not (np.isfinite(duration) and duration > 0):
        raise InvalidInputError(f"duration must be > 0 s, got {duration}")
    start, goal = np.asarray(start, dtype=float), np.asarray(goal, dtype=float)
    phi, rate, curve = smoothstep(np.asarray(times, dtype=float)[:, None] / duration)
    delta = goal - start
    return start + delta * phi, delta * rate / duration, delta * curve / duration**2


def minimum_jerk_duration(start, goal, max_speed: float, min_duration: float) -> float:
    """Shortest T >= min_duration (s) whose peak speed stays within max_speed (units/s)."""
    distance = float(np.abs(np.asarray(goal, dtype=float) - np.asarray(start, dtype=float)).max())
    return max(min_duration, MIN_JERK_PEAK_SPEED * distance / max_speed)


