"""Feasibility of a planned vibration against the vibration units and the stroke.

Limits come from config/robot.yaml through ``robot.vibration_unit``
(amplitude_max m, frequency_min/max Hz, acceleration_max m/s^2) and
``robot.limits`` (stroke_min/max m). Every failure raises a typed error
naming the leg (1..6) and the limit.
"""

from __future__ import annotations

import numpy as np

from ..errors import VibrationLimitError
from ..kinematics import inverse_kinematics
from ..kinematics.limits import check_stroke
from ..robot import STANDARD_GRAVITY, Robot, VibrationUnitLimits
from ..splines import spline_extremes


def check_frequency(robot: Robot, frequency: float) -> None:
    """VibrationLimitError(limit_name="frequency_min"/"frequency_max") outside the unit's band (Hz).

    Args:
        robot: the robot; its ``vibration_unit`` gives frequency_min / frequency_max (Hz).
        frequency: vibration frequency (Hz).

    Raises:
        VibrationLimitError: ``frequency`` is below frequency_min or above frequency_max, with
            ``leg`` None, ``limit_name``, ``value`` and ``limit`` (Hz).
    """
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
    """Per-leg peak displacement (m) and acceleration (m/s^2) [6] against the unit limits.

    Args:
        robot: the robot; its ``vibration_unit`` gives amplitude_max (m) and acceleration_max (m/s^2).
        amplitudes: peak leg vibration displacement [6] (m).
        accelerations: peak leg vibration acceleration [6] (m/s^2).

    Raises:
        VibrationLimitError: a peak exceeds its limit (by more than 1e-12 relative), amplitudes checked
            before accelerations, with ``leg`` (1..6, the leg furthest over), ``limit_name``
            ("amplitude_max" / "acceleration_max"), ``value`` and ``limit`` (m or m/s^2).
    """
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


def check_vibration_stroke(robot: Robot, nominal_lengths, low_change, high_change, extreme_poses=None) -> None:
    """Leg lengths l0 + min/max vibration change [6] within the stroke, then joints at the extremes.

    Args:
        robot: the robot; ``robot.limits`` gives stroke_min / stroke_max (m).
        nominal_lengths: nominal leg lengths l0 [6] (m).
        low_change: leg-length change at one vibration extreme [6] (m).
        high_change: leg-length change at the other extreme [6] (m); the per-leg min / max of the two is
            checked, so their order does not matter.
        extreme_poses: displaced platform poses at the vibration extremes [k, 6] (m, rad, base frame),
            checked by the inverse kinematics; None to skip.

    Raises:
        StrokeLimitError: a leg's vibrating length leaves [stroke_min, stroke_max], with ``leg`` (1..6),
            ``value`` and ``limit`` (m) of the first violation (below the minimum before above the maximum).
        InvalidInputError: ``extreme_poses`` not finite or not [..., 6].
        UnreachablePoseError, StrokeLimitError, JointLimitError: an extreme pose cannot be taken (hinge
            not above the base, stroke or joint angle), naming the sample and the leg.
    """
    nominal = np.asarray(nominal_lengths, dtype=float)
    check_stroke(nominal + np.minimum(low_change, high_change), nominal + np.maximum(low_change, high_change),
                 robot.limits, what="vibrating length")
    if extreme_poses is not None:
        inverse_kinematics(robot, extreme_poses, check_limits=True)


def check_command_limits(limits: VibrationUnitLimits, times, positions, velocities, accelerations=None) -> None:
    """Raise VibrationLimitError (leg, limit, value) if the vib_* command -- the Hermite spline through
    the knots, as the units follow it (cubic, or quintic where knots carry accelerations) -- exceeds
    the unit's displacement, velocity or acceleration limit (``splines.spline_extremes``).

    Args:
        limits: the vibration unit's limits (amplitude_max m, velocity_max m/s, acceleration_max m/s^2).
        times: knot times [n] (s).
        positions: knot vibration displacements [n, 6] (m).
        velocities: knot velocities [n, 6] (m/s).
        accelerations: knot accelerations [n, 6] (m/s^2), None or NaN rows for cubic segments.

    Raises:
        VibrationLimitError: the spline's peak |displacement|, |velocity| or |acceleration| of a leg
            exceeds amplitude_max, velocity_max or acceleration_max (by more than 1e-9 relative), checked
            in that order, with ``leg`` (1..6, the leg with the largest ratio to the limit), ``limit_name``,
            ``value`` and ``limit`` (SI units).
    """
    amax = limits.amplitude_max
    low, high, v, a = spline_extremes(times, positions, velocities, accelerations, position_bounds=(-amax, amax),
                                      velocity_bound=limits.velocity_max, acceleration_bound=limits.acceleration_max)
    p = np.maximum(np.abs(low), np.abs(high))
    checks = (
        ("amplitude_max", p, limits.amplitude_max, 1e6, "um", "displacement"),
        ("velocity_max", v, limits.velocity_max, 1e3, "mm/s", "velocity"),
        ("acceleration_max", a, limits.acceleration_max, 1.0, "m/s^2", "acceleration"),
    )
    for name, values, limit, scale, unit, what in checks:
        over = values > limit * (1.0 + 1e-9)
        if over.any():
            leg = int(np.argmax(values / limit))
            raise VibrationLimitError(
                f"vib_{leg + 1}: {what} {values[leg] * scale:.4g} {unit} exceeds the unit's {name} "
                f"{limit * scale:.4g} {unit}",
                leg=leg + 1, limit_name=name, value=float(values[leg]), limit=float(limit))
