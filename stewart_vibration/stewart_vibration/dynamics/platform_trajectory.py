"""Analytic platform trajectories: pose, twist and acceleration without finite differences.

Twist [..., 6] = [v, w] and acceleration [..., 6] = [a, alpha] of the
platform-frame origin in the base frame (SI units), as ``leg_forces`` takes
them. Any trajectory given as pose(t) with analytic first and second time
derivatives (Euler-angle rates included) converts with
``twist_from_euler_rates``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..input_checks import as_batch, unit_vector
from ..kinematics.rotations import euler_rate_matrix, rotation_from_rpy


def euler_rate_matrix_derivative(rpy, rpy_rate) -> np.ndarray:
    """dE/dt [..., 3, 3] for E(theta) of ``euler_rate_matrix`` (rpy in rad, rates in rad/s).

    Args:
        rpy: [..., 3] = [roll, pitch, yaw] (rad); only pitch and yaw enter.
        rpy_rate: their time derivatives [..., 3] (rad/s); broadcast against ``rpy``.

    Returns:
        dE/dt [..., 3, 3] (1/s), the broadcast batch shape.

    Raises:
        ValueError: the shapes of ``rpy`` and ``rpy_rate`` do not broadcast (numpy).
    """
    rpy = np.asarray(rpy, dtype=float)
    rate = np.asarray(rpy_rate, dtype=float)
    cp, cy = np.cos(rpy[..., 1]), np.cos(rpy[..., 2])
    sp, sy = np.sin(rpy[..., 1]), np.sin(rpy[..., 2])
    dp, dy = rate[..., 1], rate[..., 2]
    out = np.zeros(np.broadcast_shapes(rpy.shape, rate.shape)[:-1] + (3, 3))
    out[..., 0, 0] = -sy * cp * dy - cy * sp * dp
    out[..., 0, 1] = -cy * dy
    out[..., 1, 0] = cy * cp * dy - sy * sp * dp
    out[..., 1, 1] = -sy * dy
    out[..., 2, 0] = -cp * dp
    return out


def twist_from_euler_rates(pose, pose_rate, pose_accel) -> tuple[np.ndarray, np.ndarray]:
    """(twist, accel) [..., 6] from pose [..., 6] and its time derivatives [..., 6].

    w = E(theta) theta' and alpha = E theta'' + E' theta' (``euler_rate_matrix`` and its derivative).

    Args:
        pose: platform poses [..., 6] = [x, y, z, roll, pitch, yaw] (m, rad).
        pose_rate: [x', y', z', roll', pitch', yaw'] [..., 6] (m/s, rad/s).
        pose_accel: the second derivatives [..., 6] (m/s^2, rad/s^2).

    Returns:
        (twist, accel), each [..., 6] (the broadcast batch shape): twist [v, w] = [p', E theta'] (m/s, rad/s)
        and accel [a, alpha] = [p'', E theta'' + E' theta'] (m/s^2, rad/s^2) of the platform origin,
        base frame.

    Raises:
        InvalidInputError: an input is not numeric, not [..., 6] or not finite (``as_batch``).
        ValueError: the batch shapes do not broadcast (numpy).
    """
    pose = as_batch(pose, 6, "pose")
    rate = as_batch(pose_rate, 6, "pose_rate")
    acc = as_batch(pose_accel, 6, "pose_accel")
    e = euler_rate_matrix(pose[..., 3:])
    e_dot = euler_rate_matrix_derivative(pose[..., 3:], rate[..., 3:])
    w = np.einsum("...ij,...j->...i", e, rate[..., 3:])
    alpha = np.einsum("...ij,...j->...i", e, acc[..., 3:]) + np.einsum("...ij,...j->...i", e_dot, rate[..., 3:])
    twist = np.concatenate(np.broadcast_arrays(rate[..., :3], w), axis=-1)
    accel = np.concatenate(np.broadcast_arrays(acc[..., :3], alpha), axis=-1)
    return twist, accel


@dataclass(frozen=True)
class TrajectorySamples:
    """Samples of a platform trajectory: time [n] (s), pose, twist, accel [n, 6] (see module doc)."""

    time: np.ndarray
    pose: np.ndarray
    twist: np.ndarray
    accel: np.ndarray


@dataclass(frozen=True)
class SinusoidalTrajectory:
    """pose(t) = centre + sum_k amplitude[k] sin(omega[k] t + phase[k]) (per pose coordinate).

    centre (6,) (m, rad); amplitude [K, 6] (m, rad); omega [K] (rad/s); phase
    [K, 6] (rad). Smooth, with exact derivatives: used for vibration and for
    random test trajectories.
    """

    centre: np.ndarray
    amplitude: np.ndarray
    omega: np.ndarray
    phase: np.ndarray

    def pose_derivatives(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(pose, pose_rate, pose_accel) [n, 6] at times t [n] (s)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        om = np.asarray(self.omega, dtype=float)[:, None]
        arg = om[None] * t[:, None, None] + self.phase[None]  # [n, K, 6]
        amp = self.amplitude[None]
        pose = self.centre + (amp * np.sin(arg)).sum(axis=1)
        rate = (amp * om[None] * np.cos(arg)).sum(axis=1)
        acc = -(amp * om[None] ** 2 * np.sin(arg)).sum(axis=1)
        return pose, rate, acc

    def sample(self, t) -> TrajectorySamples:
        """Pose, twist, accel at times t [n] (s)."""
        pose, rate, acc = self.pose_derivatives(t)
        twist, accel = twist_from_euler_rates(pose, rate, acc)
        return TrajectorySamples(np.atleast_1d(np.asarray(t, dtype=float)), pose, twist, accel)


def force_line_direction(pose) -> np.ndarray:
    """Unit force-line direction = platform z axis in the base frame, [..., 3].

    Args:
        pose: platform poses [..., 6] (m, rad); only the orientation enters.

    Returns:
        R e_z [..., 3] (unit vectors, base frame).

    Raises:
        InvalidInputError: a pose is not numeric, not [..., 6] or not finite (``as_batch``).
    """
    pose = as_batch(pose, 6, "pose")
    return rotation_from_rpy(pose[..., 3:])[..., :, 2]


def vibration_trajectory(pose, direction, amplitude: float, frequency_hz: float,
                         phase: float = 0.0) -> SinusoidalTrajectory:
    """Platform at ``pose`` (6,) translating by amplitude sin(2 pi f t + phase) along ``direction``.

    The orientation stays fixed.

    Args:
        pose: centre pose (6,) (m, rad); any shape holding one [..., 6] row.
        direction: translation direction (3,) (base frame), any non-zero length (normalised here).
        amplitude: peak translation (m).
        frequency_hz: vibration frequency f (Hz).
        phase: phase (rad).

    Returns:
        SinusoidalTrajectory with centre ``pose``, one component: amplitude [1, 6] = [amplitude u, 0, 0, 0],
        omega [1] = 2 pi f (rad/s) and phase [1, 6] = ``phase``.

    Raises:
        InvalidInputError: ``pose`` is not [..., 6], or not numeric or not finite (``as_batch``); ``direction``
            is not one finite 3-vector or is zero (``unit_vector``).
        ValueError: ``pose`` holds more than one row (reshape).
    """
    pose = as_batch(pose, 6, "pose").reshape(6)
    u = unit_vector(direction, "direction")
    amp = np.zeros((1, 6))
    amp[0, :3] = amplitude * u
    return SinusoidalTrajectory(pose.copy(), amp, np.array([2 * np.pi * frequency_hz]), np.full((1, 6), phase))
