"""Feasibility of a planned vibration against the vibration units and the stroke.

Limits come from config/robot.yaml through ``robot.vibration_unit``
(amplitude_max m, frequency_min/max Hz, acceleration_max m/s^2) and
``robot.limits`` (stroke_min/max m). Every failure raises a typed error
naming the leg (1..6) and the limit.
"""

from __future__ import annotations

import numpy as np

from ..errors import StrokeLimitError, VibrationLimitError
from ..kinematics import inverse_kinematics
from ..robot import STANDARD_GRAVITY, Robot


def check_frequency(robot: Robot, frequency: float) -> None:
    """VibrationLimitError(limit_name="frequency_min"/"frequency_max") outside the unit's band (Hz)."""
    unit = robot.vibration_unit
    for bad, name, limit, word in (
        (frequency < unit.frequency_min, "frequency_min", unit.frequency_min, "below"),
        (frequency > unit.frequency_max, "frequency_max", unit.frequency_max, "above"),
    ):
        if bad:
            raise VibrationLimitError(
                f"vibration frequency {frequency:.6g} Hz is {word} the vibration unit's band "
                f"[{unit.frequency_min:.6g}, {unit.frequency_max:.6g}] Hz ({name})",
                leg=None, limit_name=name, value=float(frequency), limit=float(limit),
            )


def check_leg_peaks(robot: Robot, amplitudes, accelerations) -> None:
    """Per-leg peak displacement (m) and acceleration (m/s^2) [6] against the unit limits."""
    unit = robot.vibration_unit
    for values, limit, name, unit_text, scale in (
        (np.asarray(amplitudes, float), unit.amplitude_max, "amplitude_max", "um", 1e6),
        (np.asarray(accelerations, float), unit.acceleration_max, "acceleration_max", "g", 1 / STANDARD_GRAVITY),
    ):
        over = values > limit * (1.0 + 1e-12)
        if over.any():
            leg = int(np.argmax(values - limit))
            raise VibrationLimitError(
                f"leg {leg + 1}: vibration peak {values[leg] * scale:.6g} {unit_text} exceeds the vibration "
                f"unit's {name} {limit * scale:.6g} {unit_text}",
                leg=leg + 1, limit_name=name, value=float(values[leg]), limit=float(limit),
            )


def check_stroke(robot: Robot, nominal_lengths, low_change, high_change, extreme_poses=None) -> None:
    """Leg lengths l0 + min/max vibration change [6] within the stroke, then joints at the extremes.

    StrokeLimitError(leg=, value=, limit=) names the leg whose vibrating
    length leaves [stroke_min, stroke_max]; ``extreme_poses`` [k, 6] (the
    displaced platform poses at the vibration extremes) are also checked for
    joint limits by the inverse kinematics.
    """
    lim = robot.limits
    lowest = np.asarray(nominal_lengths) + np.minimum(low_change, high_change)
    highest = np.asarray(nominal_lengths) + np.maximum(low_change, high_change)
    for mask, values, limit, word in (
        (lowest < lim.stroke_min, lowest, lim.stroke_min, "below the minimum"),
        (highest > lim.stroke_max, highest, lim.stroke_max, "above the maximum"),
    ):
        if mask.any():
            leg = int(np.argmax(mask))
            value = float(values[leg])
            raise StrokeLimitError(
                f"leg {leg + 1}: vibrating length reaches {value:.6f} m, {abs(value - limit) * 1e6:.3f} um "
                f"{word} stroke {limit:.6f} m",
                leg=leg + 1, value=value, limit=limit,
            )
    if extreme_poses is not None:
        inverse_kinematics(robot, extreme_poses, check_limits=True)
