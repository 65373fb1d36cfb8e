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

    Args:
        start: start coordinates [dim] (any unit).
        goal: goal coordinates [dim] (same unit).
        duration: move duration T (s), > 0.
        times: sample times [n] (s), clamped to [0, T].

    Returns:
        (positions, velocities, accelerations), each [n, dim] (unit, unit/s, unit/s^2).

    Raises:
        InvalidInputError: ``duration`` is not finite or not > 0.
    """
    if not (np.isfinite(duration) and duration > 0):
        raise InvalidInputError(f"duration must be > 0 s, got {duration}")
    start, goal = np.asarray(start, dtype=float), np.asarray(goal, dtype=float)
    phi, rate, curve = smoothstep(np.asarray(times, dtype=float)[:, None] / duration)
    delta = goal - start
    return start + delta * phi, delta * rate / duration, delta * curve / duration**2


def minimum_jerk_duration(start, goal, max_speed: float, min_duration: float) -> float:
    """Shortest T >= min_duration (s) whose peak speed stays within max_speed (units/s).

    Args:
        start: start coordinates [dim].
        goal: goal coordinates [dim].
        max_speed: speed limit of every coordinate (units/s), > 0.
        min_duration: shortest accepted duration (s).

    Returns:
        T = max(min_duration, 1.875 max_k |goal_k - start_k| / max_speed) (s).
    """
    distance = float(np.abs(np.asarray(goal, dtype=float) - np.asarray(start, dtype=float)).max())
    return max(min_duration, MIN_JERK_PEAK_SPEED * distance / max_speed)


