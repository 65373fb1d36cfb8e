"""Decomposition: a desired platform vibration -> six leg vibration equations.

The platform vibrates by delta(t) = A sin(2 pi f t + phase) along a screw
(the paper's section 4, corrected): a translation along the unit direction u (the force
line; default the platform z axis, the tibia axis) or a small rotation about
an axis through a point. To first order leg i gets k_i delta(t) with
k_i = J_i s (for a translation k_i = n_i . u): every leg carries the same
frequency and phase, with the signed gain k_i (k_i < 0 is the same
vibration in antiphase, phase + pi). The ``exact`` method also samples the
leg signals from the inverse kinematics of the displaced poses, which adds
the second-order DC offset and second harmonic
dl_i = k_i delta + l''_i delta^2 / 2, l''_i = (1 - k_i^2) / l_i for a translation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError
from ..input_checks import as_batch
from ..kinematics import inverse_kinematics
from ..kinematics.rotations import rotation_from_rpy
from ..paper import CLINICAL_ACCELERATION_G, CLINICAL_FREQUENCY_HZ
from ..robot import Robot
from .feasibility import check_frequency, check_leg_peaks, check_vibration_stroke
from .screw import (
    VibrationScrew,
    displaced_poses,
    leg_length_change,
    nominal_leg_geometry,
    twist_per_unit,
    unit_vector,
)
from .waveform import default_times, displacement_from_acceleration, sinusoid

FRAMES = ("platform", "base")
METHODS = ("exact", "linear")


def wrap_phase(phase):
    """Phase wrapped to [0, 2 pi) (rad).

    Args:
        phase: phase(s) (rad), a scalar or an array of any shape.

    Returns:
        ``phase`` mod 2 pi, in [0, 2 pi) (rad), same shape as ``phase``.
    """
    return np.mod(phase, 2.0 * np.pi)


@dataclass(frozen=True)
class VibrationDecomposition:
    """Six leg vibration equations for one platform vibration (SI units, base frame).

    Leg i: vib_i(t) = leg_amplitudes[i] sin(2 pi frequency t + leg_phases[i])
    to first order, = gains[i] * A sin(2 pi f t + phase).

    pose (6,) nominal platform pose; screw: the vibration direction/axis in
    the base frame; twist (6,) [dp; dphi] per unit delta; amplitude A (m for a
    translation, rad for a rotation), frequency (Hz), phase (rad);
    gains k_i (6,) (m per unit delta), leg_amplitudes |k_i| A (6,, m),
    leg_phases (6,, rad, phase or phase + pi, in [0, 2 pi));
    nominal_lengths l_i (6,, m); curvature l''_i (6,, m per unit delta^2):
    second-order DC offset and second-harmonic amplitude are both
    curvature A^2 / 4; times (N,, s); delta (N,) platform displacement;
    linear_signals (N, 6) k_i delta (m); exact_signals (N, 6) IK difference
    (m) or None for method "linear"; peak_change_low/high (6,) exact leg
    change at delta = -A / +A (m); peak_leg_acceleration (6,, m/s^2).
    """

    pose: np.ndarray
    frame: str
    method: str
    screw: VibrationScrew
    twist: np.ndarray
    amplitude: float
    frequency: float
    phase: float
    gains: np.ndarray
    leg_amplitudes: np.ndarray
    leg_phases: np.ndarray
    nominal_lengths: np.ndarray
    curvature: np.ndarray
    times: np.ndarray
    delta: np.ndarray
    linear_signals: np.ndarray
    exact_signals: np.ndarray | None
    peak_change_low: np.ndarray
    peak_change_high: np.ndarray
    peak_leg_acceleration: np.ndarray

    @property
    def angular_frequency(self) -> float:
        """omega = 2 pi f (rad/s)."""
        return 2.0 * np.pi * self.frequency

    @property
    def direction(self) -> np.ndarray:
        """Unit translation direction (base frame), or the rotation axis for a rotation."""
        return self.screw.axis if self.screw.rotational else self.screw.translation

    @property
    def second_order_offset(self) -> np.ndarray:
        """Predicted DC offset and second-harmonic amplitude l''_i A^2 / 4 (6,, m)."""
        return self.curvature * self.amplitude**2 / 4.0

    @property
    def leg_vibrations(self) -> np.ndarray:
        """(6, 3) [amplitude m, frequency Hz, phase rad] per leg, the input of superpose_vibration."""
        return np.column_stack([self.leg_amplitudes, np.full(6, self.frequency), self.leg_phases])

    def equations(self) -> list[str]:
        """Human-readable leg equations, e.g. 'vib_1(t) = 12.3 um sin(219.91 t + 3.1416)'."""
        return [
            f"vib_{i + 1}(t) = {a * 1e6:.6g} um * sin({self.angular_frequency:.6g} t + {p:.6g})"
            for i, (a, p) in enumerate(zip(self.leg_amplitudes, self.leg_phases))
        ]


def make_screw(pose, direction=None, frame="platform", rotation_axis=None, rotation_point=None) -> VibrationScrew:
    """The vibration screw in the base frame from a direction or a rotation axis (+ point).

    frame "platform": vectors/point in the platform frame at ``pose`` (point
    relative to the platform origin); "base": in the base frame. A rotation axis
    passes through ``rotation_point`` (default the platform origin).

    Args:
        pose: nominal platform pose (6,) [x, y, z, roll, pitch, yaw] (m, rad), base frame.
        direction: translation direction (3,), any non-zero length, in ``frame``; default [0, 0, 1] in
            ``frame`` (for frame "platform" the platform z axis, the tibia axis). Not with ``rotation_axis``.
        frame: "platform" or "base", the frame of ``direction``, ``rotation_axis`` and ``rotation_point``.
        rotation_axis: rotation axis (3,), any non-zero length, in ``frame``; None for a translation.
        rotation_point: a point on the rotation axis (3,) (m), in ``frame``; only with ``rotation_axis``.

    Returns:
        VibrationScrew in the base frame: for a translation ``translation`` = unit u and zero ``axis`` and
        ``point``; for a rotation zero ``translation``, unit ``axis`` w and ``point`` c (m).

    Raises:
        InvalidInputError: ``frame`` is not "platform" or "base"; both ``direction`` and ``rotation_axis``
            are given; ``rotation_point`` is given without ``rotation_axis``; ``direction`` or
            ``rotation_axis`` is not one finite 3-vector or is zero (``unit_vector``); ``rotation_point``
            is not numeric, not finite or not [..., 3].
    """
    if frame not in FRAMES:
        raise InvalidInputError(f"frame must be one of {FRAMES}, got {frame!r}")
    pose = np.asarray(pose, dtype=float)
    rot0 = rotation_from_rpy(pose[3:])
    to_base = rot0 if frame == "platform" else np.eye(3)
    zero = np.zeros(3)
    if rotation_axis is not None:
        if direction is not None:
            raise InvalidInputError("give either direction (translation) or rotation_axis (rotation), not both")
        axis = to_base @ unit_vector(rotation_axis, "rotation_axis")
        if rotation_point is None:
            point = pose[:3].copy()
        else:
            local = as_batch(rotation_point, 3, "rotation_point").reshape(3)
            point = pose[:3] + rot0 @ local if frame == "platform" else local
        return VibrationScrew(translation=zero, axis=axis, point=point)
    if rotation_point is not None:
        raise InvalidInputError("rotation_point needs rotation_axis")
    u = unit_vector([0.0, 0.0, 1.0] if direction is None else direction, "direction")
    return VibrationScrew(translation=to_base @ u, axis=zero, point=zero)


def resolve_amplitude(amplitude, acceleration_g, frequency: float, rotational: bool) -> float:
    """Platform amplitude A (m, or rad for a rotation) from a displacement or an acceleration (g).

    An acceleration is converted with X = a g0 / (2 pi f)^2 (``displacement_from_acceleration``).

    Args:
        amplitude: peak displacement A (m; rad for a rotation), or None to use ``acceleration_g``.
        acceleration_g: peak acceleration (g), or None; with both None a translation gets the clinical
            CLINICAL_ACCELERATION_G (0.3 g).
        frequency: vibration frequency f (Hz, > 0).
        rotational: True for a rotation screw, which needs ``amplitude`` in rad.

    Returns:
        A as a float (m for a translation, rad for a rotation).

    Raises:
        InvalidInputError: both ``amplitude`` and ``acceleration_g`` are given; a rotation has no
            ``amplitude``; ``acceleration_g`` or ``amplitude`` is not finite or not > 0.
    """
    if amplitude is not None and acceleration_g is not None:
        raise InvalidInputError("give either amplitude (m) or acceleration_g (g), not both")
    if amplitude is None:
        if rotational:
            if acceleration_g is not None:
                raise InvalidInputError("acceleration_g applies to translations; give a rotation amplitude in rad")
            raise InvalidInputError("a rotational vibration needs amplitude (rad)")
        acceleration_g = CLINICAL_ACCELERATION_G if acceleration_g is None else acceleration_g
        if not np.isfinite(acceleration_g) or acceleration_g <= 0:
            raise InvalidInputError(f"acceleration_g must be > 0, got {acceleration_g}")
        return displacement_from_acceleration(acceleration_g, frequency)
    if not np.isfinite(amplitude) or amplitude <= 0:
        raise InvalidInputError(f"amplitude must be > 0, got {amplitude}")
    return float(amplitude)


def decompose_vibration(
    robot: Robot,
    pose,
    direction=None,
    amplitude: float | None = None,
    frequency: float = CLINICAL_FREQUENCY_HZ,
    phase: float = 0.0,
    *,
    frame: str = "platform",
    method: str = "exact",
    acceleration_g: float | None = None,
    times=None,
    duration: float | None = None,
    samples_per_period: int = 256,
    rotation_axis=None,
    rotation_point=None,
    check_limits: bool = True,
) -> VibrationDecomposition:
    """Decompose the platform vibration delta(t) = A sin(2 pi f t + phase) into six leg vibrations.

    Leg i gets k_i delta(t) to first order (k_i = J_i s); method "exact" also samples the inverse
    kinematics of the displaced poses (second-order DC offset and second harmonic included) and checks
    limits on them, "linear" gives only k_i delta. An acceleration is converted with X = a / (2 pi f)^2.

    Args:
        robot: the robot.
        pose: nominal platform pose (6,) [x, y, z, roll, pitch, yaw] (m, rad), base frame.
        direction: translation direction (3,), any length, in ``frame`` (default [0, 0, 1]: in the
            platform frame the tibia axis). For a rotational vibration give ``rotation_axis`` instead.
        amplitude: peak displacement A (m; rad for a rotation); or give ``acceleration_g``; neither:
            the clinical 0.3 g (translations only).
        frequency: vibration frequency f (Hz, > 0).
        phase: vibration phase (rad).
        frame: "platform" (vectors/point in the platform frame at ``pose``) or "base".
        method: "exact" or "linear".
        acceleration_g: peak platform acceleration (g), for a translation.
        times: sample times [N] (s); default from ``duration``.
        duration: duration (s) sampled when ``times`` is None; default one period.
        samples_per_period: samples per period (>= 8) when ``times`` is None.
        rotation_axis: rotation axis (3,) in ``frame`` for a rotational vibration (amplitude in rad).
        rotation_point: a point on the rotation axis (3,) (m) in ``frame``; default the platform origin.
        check_limits: check the frequency band, the pose, the per-leg peaks and the vibration excursion.

    Returns:
        VibrationDecomposition (base frame, SI units): per-leg gains, amplitudes |k_i| A and phases
        (phase or phase + pi), ``linear_signals`` [N, 6] (m), ``exact_signals`` [N, 6] (m; None for
        method "linear"), peak changes and peak leg accelerations [6].

    Raises:
        InvalidInputError: ``method`` or ``frame`` unknown; ``pose`` not one finite (6,) pose;
            ``frequency`` or ``phase`` not finite, or ``frequency`` <= 0; a bad ``direction``,
            ``rotation_axis``, ``rotation_point`` or amplitude (``make_screw``, ``resolve_amplitude``);
            ``times`` not a finite 1-D array, ``samples_per_period`` < 8 or ``duration`` <= 0.
        VibrationLimitError: with ``check_limits``, the frequency is outside the vibration unit's band,
            or a leg's peak amplitude or acceleration exceeds the unit's limit.
        UnreachablePoseError, StrokeLimitError, JointLimitError: with ``check_limits``, the nominal pose
            or the displaced poses at delta = -A / +A cannot be taken, or a leg's vibrating length leaves
            the stroke.
    """
    if method not in METHODS:
        raise InvalidInputError(f"method must be one of {METHODS}, got {method!r}")
    pose = as_batch(pose, 6, "pose")
    if pose.shape != (6,):
        raise InvalidInputError(f"pose: expected one pose (6,), got shape {list(pose.shape)}")
    for name, value in (("frequency", frequency), ("phase", phase)):
        if not np.isfinite(value):
            raise InvalidInputError(f"{name} must be finite, got {value}")
    if frequency <= 0:
        raise InvalidInputError(f"frequency must be > 0 Hz, got {frequency}")
    if check_limits:
        check_frequency(robot, frequency)
        inverse_kinematics(robot, pose, check_limits=True)
    screw = make_screw(pose, direction, frame, rotation_axis, rotation_point)
    amp = resolve_amplitude(amplitude, acceleration_g, frequency, screw.rotational)

    _, _, l0, jac = nominal_leg_geometry(robot, pose)
    twist = twist_per_unit(screw, pose[:3])
    gains = jac @ twist
    omega = 2.0 * np.pi * frequency
    t = default_times(frequency, duration, samples_per_period) if times is None else np.asarray(times, float)
    if t.ndim != 1 or not np.isfinite(t).all():
        raise InvalidInputError("times must be a finite 1-D array (s)")
    delta, _, _ = sinusoid(t, amp, frequency, phase)
    linear = delta[:, None] * gains

    extremes = leg_length_change(robot, pose, screw, np.array([-amp, 0.0, amp]))
    low, high = extremes.change[0], extremes.change[2]
    curvature = extremes.curvature[1]
    exact = leg_length_change(robot, pose, screw, delta).change if method == "exact" else None

    if method == "exact":
        # peak of d2/dt2 l(delta(t)) = l' delta'' + l'' delta'^2 over one dense period
        grid = np.linspace(0.0, 1.0 / frequency, 513)
        dg, vg, ag = sinusoid(grid, amp, frequency, 0.0)
        along = leg_length_change(robot, pose, screw, dg)
        peak_acc = np.abs(along.slope * ag[:, None] + along.curvature * vg[:, None] ** 2).max(axis=0)
        peak_amp = np.maximum(np.abs(low), np.abs(high))
    else:
        peak_acc = np.abs(gains) * amp * omega**2
        peak_amp = np.abs(gains) * amp
        low, high = -peak_amp, peak_amp

    if check_limits:
        check_leg_peaks(robot, peak_amp, peak_acc)
        extreme_poses = displaced_poses(screw, pose, np.array([-amp, amp]))[2]
        check_vibration_stroke(robot, l0, low, high, extreme_poses)

    return VibrationDecomposition(
        pose=pose.copy(), frame=frame, method=method, screw=screw, twist=twist,
        amplitude=amp, frequency=float(frequency), phase=float(phase),
        gains=gains, leg_amplitudes=np.abs(gains) * amp,
        leg_phases=wrap_phase(np.where(gains < 0, phase + np.pi, phase)),
        nominal_lengths=l0, curvature=curvature, times=t, delta=delta,
        linear_signals=linear, exact_signals=exact,
        peak_change_low=low, peak_change_high=high, peak_leg_acceleration=peak_acc,
    )
