"""Planner helpers: leg vibration commands vib_i(t) and the planned platform motion.

Both use the ramped waveform delta(t) = e(t) A sin(2 pi f t + phase) of
``waveform.sinusoid`` (t in s from the common start stamp). Leg commands
are either exact (vib_i = l_i(pose displaced by delta) - l_i(pose), so the
platform moves exactly along the screw) or linear (k_i delta). The platform
motion returned is the planned one (exact for exact commands; the linear
commands reproduce it to second order in A).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError
from ..input_checks import as_batch
from .decompose import VibrationDecomposition
from .screw import displaced_poses, leg_length_change
from .waveform import sinusoid


@dataclass(frozen=True)
class LegVibrationSamples:
    """vib_i samples: times (N,, s); position (N, 6, m); velocity (N, 6, m/s); acceleration (N, 6, m/s^2)."""

    times: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray


@dataclass(frozen=True)
class PlatformVibrationMotion:
    """Planned platform motion, base frame: times (N,, s); pose (N, 6) [m, rad];
    position (N, 3, m) and rotation (N, 3, 3) of the platform frame;
    velocity (N, 3, m/s) and acceleration (N, 3, m/s^2) of the platform
    origin; angular_velocity (N, 3, rad/s) and angular_acceleration (N, 3, rad/s^2)."""

    times: np.ndarray
    pose: np.ndarray
    position: np.ndarray
    rotation: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    angular_velocity: np.ndarray
    angular_acceleration: np.ndarray


def _waveform(plan: VibrationDecomposition, times, duration, ramp_time, fade=None):
    t = np.asarray(times, dtype=float)
    if t.ndim != 1 or not np.isfinite(t).all():
        raise InvalidInputError("times must be a finite 1-D array (s)")
    return t, sinusoid(t, plan.amplitude, plan.frequency, plan.phase, duration, ramp_time, fade)


def sample_leg_vibration(
    robot, plan: VibrationDecomposition, times, *, duration: float | None = None,
    ramp_time: float = 0.0, method: str = "exact", fade=None,
) -> LegVibrationSamples:
    """Leg vibration displacement vib_i(t) [N, 6] (m) with velocity and acceleration.

    method "exact": IK difference of the displaced poses (velocity l' delta',
    acceleration l' delta'' + l'' delta'^2, analytic); "linear": k_i delta(t).

    Args:
        robot: the robot.
        plan: the vibration (screw, amplitude, frequency, phase, gains).
        times: times [N] (s from the vibration start).
        duration: end of the vibration (s), or None for no end.
        ramp_time: smooth quintic ramp-in/out of the platform displacement (s).
        method: "exact" or "linear".
        fade: an extra envelope (g, g', g'') [N] on delta (``waveform.fade_out``: the ramp-out that
            ends a streamed window or a stop), or None.

    Returns:
        LegVibrationSamples: times [N] (s), position [N, 6] (m), velocity [N, 6] (m/s) and
        acceleration [N, 6] (m/s^2).

    Raises:
        InvalidInputError: ``times`` is not a finite 1-D array; ``ramp_time`` is negative or not finite,
            or two ramps do not fit in ``duration``; ``method`` is unknown.
    """
    t, (delta, rate, accel) = _waveform(plan, times, duration, ramp_time, fade)
    if method == "linear":
        k = plan.gains
        return LegVibrationSamples(t, delta[:, None] * k, rate[:, None] * k, accel[:, None] * k)
    if method != "exact":
        raise InvalidInputError(f"method must be 'exact' or 'linear', got {method!r}")
    change = leg_length_change(robot, plan.pose, plan.screw, delta)
    return LegVibrationSamples(
        t, change.change, change.slope * rate[:, None],
        change.slope * accel[:, None] + change.curvature * rate[:, None] ** 2,
    )


def platform_vibration_motion(
    plan: VibrationDecomposition, times, *, duration: float | None = None, ramp_time: float = 0.0,
) -> PlatformVibrationMotion:
    """Analytic planned platform pose, velocity and acceleration (base frame) for times [N] (s).

    With s = u for a translation: v = u delta', a = u delta''. For a rotation
    about the axis w through c, with r = p(t) - c: omega = w delta',
    alpha = w delta'', v = w x r delta', a = w x r delta'' + w x (w x r) delta'^2.

    Args:
        plan: the vibration (nominal pose, screw, amplitude, frequency, phase).
        times: times [N] (s from the vibration start).
        duration: end of the vibration (s), or None for no end.
        ramp_time: smooth quintic ramp-in/out (s).

    Returns:
        PlatformVibrationMotion (base frame): pose [N, 6] (m, rad), position [N, 3] (m), rotation
        [N, 3, 3], velocity [N, 3] (m/s), acceleration [N, 3] (m/s^2), angular_velocity [N, 3] (rad/s),
        angular_acceleration [N, 3] (rad/s^2).

    Raises:
        InvalidInputError: ``times`` is not a finite 1-D array; ``ramp_time`` is negative or not finite,
            or two ramps do not fit in ``duration``.
    """
    t, (delta, rate, accel) = _waveform(plan, times, duration, ramp_time)
    screw = plan.screw
    position, rotation, poses = displaced_poses(screw, as_batch(plan.pose, 6, "pose"), delta)
    w = screw.axis
    arm = position - screw.point
    lin = screw.translation + np.cross(w, arm)
    centripetal = np.cross(w, np.cross(w, arm))
    return PlatformVibrationMotion(
        times=t, pose=poses, position=position, rotation=rotation,
        velocity=lin * rate[:, None],
        acceleration=lin * accel[:, None] + centripetal * rate[:, None] ** 2,
        angular_velocity=w * rate[:, None], angular_acceleration=w * accel[:, None],
    )
