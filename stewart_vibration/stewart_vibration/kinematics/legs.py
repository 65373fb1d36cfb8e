"""Leg (strut) velocities and accelerations from the platform motion (Newton-Euler, docs/dynamics.md).

Frames and units: everything in the base frame, SI (m, rad, s). The platform
twist is [v, w]: v the velocity of the platform-frame origin, w the angular
velocity; the acceleration is [a, alpha] of the same point. Both [..., 6].

Each leg is a cylinder turning about the base hinge B_i and a piston sliding
in it, ending in the platform hinge A_i. The leg's spin about its own axis is
ignored (w_i is perpendicular to s_i), the standard UPS assumption; with a
universal joint at B_i the real cylinder spins slightly (see
``stewart_vibration.dynamics.mujoco_validation.leg_spin_force_correction``).

Internally vectors are stored component-first ([3, 6, n], "SoA") so that the
batched arithmetic runs on contiguous arrays; ``leg_motion`` returns the
usual [..., 6, 3] layout.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..input_checks import as_batch
from ..robot import Robot
from .rotations import rotation_from_rpy


def cross_first_axis(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b for component-first arrays [3, ...].

    Args:
        a: vectors, component-first [3, ...].
        b: vectors, component-first [3, ...] (broadcast against ``a``).

    Returns:
        The cross products [3, ...] (broadcast shape).
    """
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]
    return out


def dot_first_axis(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a . b for component-first arrays [3, ...] -> [...].

    Args:
        a: vectors, component-first [3, ...].
        b: vectors, component-first [3, ...] (broadcast against ``a``).

    Returns:
        The dot products [...] (broadcast shape without the component axis).
    """
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@dataclass(frozen=True)
class LegMotion:
    """Leg kinematics, base frame, SI units.

    Vectors are [..., 6, 3] (``leg_motion``) or component-first [3, 6, n]
    (internal ``leg_motion_soa``). rotation: platform R; arm: r_i = R a_i (m);
    axis: unit s_i; length l (m), length_rate l_dot (m/s), length_accel
    l_ddot (m/s^2); omega w_i and alpha alpha_i: leg angular velocity (rad/s)
    and acceleration (rad/s^2), both normal to s_i; axis_rate
    s_dot = w_i x s_i; axis_accel s_ddot = alpha_i x s_i + w_i x (w_i x s_i);
    hinge_velocity / hinge_accel: velocity / acceleration of A_i.
    """

    rotation: np.ndarray
    arm: np.ndarray
    axis: np.ndarray
    length: np.ndarray
    length_rate: np.ndarray
    length_accel: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    axis_rate: np.ndarray
    axis_accel: np.ndarray
    hinge_velocity: np.ndarray
    hinge_accel: np.ndarray


def hinge_arms(robot: Robot, rot_t: np.ndarray) -> np.ndarray:
    """r_i = R a_i as [3, 6, n] from rot_t = R laid out [3, 3, n].

    Args:
        robot: the robot (its platform hinges a_i, platform frame, m).
        rot_t: platform rotations R laid out [3, 3, n] (row, column, sample).

    Returns:
        Hinge arms r_i = R a_i, component-first [3, 6, n] (base frame, m).
    """
    a = robot.platform_hinges
    return (rot_t[:, 0, None, :] * a[None, :, 0, None] + rot_t[:, 1, None, :] * a[None, :, 1, None]
            + rot_t[:, 2, None, :] * a[None, :, 2, None])


def leg_axes(robot: Robot, pose: np.ndarray):
    """Step 1 on poses [6, n]: rotation, hinge arms, leg lengths and unit leg axes.

    Args:
        robot: the robot.
        pose: platform poses laid out [6, n] = [x, y, z, roll, pitch, yaw] (m, rad), not validated.

    Returns:
        (rot_t, r, length, inv_l, s): R as [3, 3, n], arms r_i = R a_i [3, 6, n] (m), leg lengths l [6, n]
        (m), 1 / l [6, n] (1/m) and unit leg axes s_i [3, 6, n]; vectors in the base frame.
    """
    rot_t = np.ascontiguousarray(rotation_from_rpy(pose[3:].T).transpose(1, 2, 0))
    r = hinge_arms(robot, rot_t)
    d = r + (pose[:3, None, :] - robot.base_hinges.T[:, :, None])
    length = np.sqrt(dot_first_axis(d, d))
    inv_l = 1.0 / length
    return rot_t, r, length, inv_l, d * inv_l


def hinge_motion(arm: np.ndarray, twist: np.ndarray, accel: np.ndarray):
    """Step 2: velocity and acceleration of A_i [3, 6, n] from arms r_i and the platform twist/accel [6, n].

    Args:
        arm: hinge arms r_i = R a_i [3, 6, n] (base frame, m).
        twist: platform twist [v, w] laid out [6, n] (m/s, rad/s; base frame).
        accel: platform acceleration [a, alpha] laid out [6, n] (m/s^2, rad/s^2; base frame).

    Returns:
        (velocity, acceleration) of the platform hinges A_i, each [3, 6, n] (m/s, m/s^2; base frame):
        v + w x r_i and a + alpha x r_i + w x (w x r_i).
    """
    w, alpha = twist[3:, None, :], accel[3:, None, :]
    w_x_r = cross_first_axis(w, arm)
    return twist[:3, None, :] + w_x_r, accel[:3, None, :] + cross_first_axis(alpha, arm) + cross_first_axis(w, w_x_r)


def leg_motion_soa(robot: Robot, pose: np.ndarray, twist: np.ndarray, accel: np.ndarray) -> LegMotion:
    """Steps 1-3 on validated inputs laid out [6, n]; vectors returned as [3, 6, n], scalars [6, n].

    Args:
        robot: the robot.
        pose: platform poses [6, n] (m, rad).
        twist: platform twists [v, w] [6, n] of the platform origin (m/s, rad/s; base frame).
        accel: platform accelerations [a, alpha] [6, n] (m/s^2, rad/s^2; base frame).

    Returns:
        LegMotion with vectors [3, 6, n], scalars [6, n] and ``rotation`` as [3, 3, n] (base frame, SI).
    """
    rot_t, r, length, inv_l, s = leg_axes(robot, pose)
    v_a, a_a = hinge_motion(r, twist, accel)
    l_dot = dot_first_axis(s, v_a)
    omega = cross_first_axis(s, v_a) * inv_l
    l_ddot = dot_first_axis(s, a_a) + length * dot_first_axis(omega, omega)
    leg_alpha = (cross_first_axis(s, a_a) - 2.0 * l_dot * omega) * inv_l
    s_dot = cross_first_axis(omega, s)
    s_ddot = cross_first_axis(leg_alpha, s) + cross_first_axis(omega, s_dot)
    return LegMotion(rot_t, r, s, length, l_dot, l_ddot, omega, leg_alpha, s_dot, s_ddot, v_a, a_a)


def flat_inputs(pose, twist, accel) -> tuple[tuple, np.ndarray, np.ndarray, np.ndarray]:
    """Validate and broadcast [..., 6] inputs; return (batch shape, pose, twist, accel laid out [6, n]).

    Args:
        pose: platform poses [..., 6] (m, rad).
        twist: platform twists [..., 6] = [v, w] (m/s, rad/s).
        accel: platform accelerations [..., 6] = [a, alpha] (m/s^2, rad/s^2).

    Returns:
        (batch, pose, twist, accel): the broadcast batch shape (a tuple) and the three inputs as contiguous
        [6, n] arrays, n the number of samples.

    Raises:
        InvalidInputError: an input is not numeric, not [..., 6] or not finite (``as_batch``).
        ValueError: the three batch shapes do not broadcast (numpy).
    """
    pose = as_batch(pose, 6, "pose")
    twist = as_batch(twist, 6, "twist")
    accel = as_batch(accel, 6, "accel")
    shape = np.broadcast_shapes(pose.shape, twist.shape, accel.shape)
    flat = [np.ascontiguousarray(np.broadcast_to(x, shape).reshape(-1, 6).T) for x in (pose, twist, accel)]
    return shape[:-1], *flat  # type: ignore[return-value]  # flat: three arrays (mypy sees a list)


def leg_motion(robot: Robot, pose, twist, accel) -> LegMotion:
    """Steps 1-3: leg lengths, axes, rates and angular motion from the platform motion.

    Args:
        robot: the robot.
        pose: platform poses [..., 6] (m, rad).
        twist: platform twists [..., 6] = [v, w] of the platform origin (m/s, rad/s; base frame).
        accel: platform accelerations [..., 6] = [a, alpha] of the same point (m/s^2, rad/s^2; base frame).
            The three shapes broadcast.

    Returns:
        LegMotion (base frame, SI) with vectors [..., 6, 3], scalars [..., 6] and rotation [..., 3, 3].

    Raises:
        InvalidInputError: an input is not numeric, not [..., 6] or not finite (``as_batch``).
        ValueError: the three batch shapes do not broadcast (numpy).
    """
    batch, pose, twist, accel = flat_inputs(pose, twist, accel)
    soa = leg_motion_soa(robot, pose, twist, accel)
    out = {}
    for name, value in vars(soa).items():
        if name == "rotation":
            out[name] = value.transpose(2, 0, 1).reshape(batch + (3, 3))
        elif value.ndim == 3:
            out[name] = value.transpose(2, 1, 0).reshape(batch + (6, 3))
        else:
            out[name] = value.T.reshape(batch + (6,))
    return LegMotion(**out)
