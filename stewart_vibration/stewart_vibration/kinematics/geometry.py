"""Leg geometry of the 6-UPS platform: leg vectors, hinge arms and joint angles (batched numpy).

Notation (the general form of the paper's eqs 4-11): b_i base hinge (base frame), a_i platform
hinge (platform frame), pose q = [x, y, z, roll, pitch, yaw] with p = q[:3] and
R = Rz(yaw) Ry(pitch) Rx(roll) (eq. 3); d_i = p + R a_i - b_i (eq. 4), l_i = |d_i|, n_i = d_i / l_i.
"""

from __future__ import annotations

import numpy as np

from ..input_checks import as_batch
from ..robot import Robot, derived
from .rotations import rotation_from_rpy


def hinge_map(robot: Robot) -> np.ndarray:
    """Constant matrix C with (R.reshape(9) @ C).reshape(6, 3) = R a_i for all six legs.

    Args:
        robot: the robot whose platform hinges a_i (platform frame, m) C holds.

    Returns:
        C, shape (9, 18) (cached per robot).
    """

    def build() -> np.ndarray:
        cmap = np.zeros((9, 18))
        for leg, a in enumerate(robot.platform_hinges):
            for m in range(3):
                cmap[3 * m : 3 * m + 3, 3 * leg + m] = a
        return cmap

    return derived(robot, "hinge_map", build)


def leg_vectors_from_rotation(robot: Robot, position: np.ndarray, rotation: np.ndarray):
    """Leg vectors and hinge arms for platform positions and rotation matrices.

    R a_i for all legs is one matrix product with the constant ``hinge_map``.

    Args:
        robot: the robot.
        position: platform origin p, shape [..., 3] (base frame, m).
        rotation: platform rotation R, shape [..., 3, 3].

    Returns:
        (d, r): leg vectors d_i = p + R a_i - b_i and arms r_i = R a_i, each [..., 6, 3] (base frame, m).
    """
    batch = rotation.shape[:-2]
    r = (rotation.reshape(batch + (9,)) @ hinge_map(robot)).reshape(batch + (6, 3))
    d = r + (position[..., None, :] - robot.base_hinges)
    return d, r


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b over the last axis (faster than np.cross for small batches).

    Args:
        a: vectors [..., 3].
        b: vectors [..., 3] (broadcast against ``a``).

    Returns:
        The cross products [..., 3].
    """
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def leg_vectors(robot: Robot, poses) -> np.ndarray:
    """Leg vectors d_i = p + R a_i - b_i (paper eq. 4).

    Args:
        robot: the robot.
        poses: platform poses [..., 6] = [x, y, z, roll, pitch, yaw] (m, rad).

    Returns:
        d_i, shape [..., 6, 3] (base frame, m).

    Raises:
        InvalidInputError: a pose is not finite or not [..., 6].
    """
    poses = as_batch(poses, 6, "pose")
    return leg_vectors_from_rotation(robot, poses[..., :3], rotation_from_rpy(poses[..., 3:]))[0]


def joint_angles(robot: Robot, poses) -> tuple[np.ndarray, np.ndarray]:
    """Universal (base) and spherical (platform) joint angles of every leg.

    Args:
        robot: the robot.
        poses: platform poses [..., 6] (m, rad).

    Returns:
        (universal, spherical), each [..., 6] (rad): the leg axis n_i against the base z axis and
        against the platform z axis R e_z.

    Raises:
        InvalidInputError: a pose is not finite or not [..., 6].
    """
    poses = as_batch(poses, 6, "pose")
    rot = rotation_from_rpy(poses[..., 3:])
    d, _ = leg_vectors_from_rotation(robot, poses[..., :3], rot)
    n = d / np.linalg.norm(d, axis=-1, keepdims=True)
    return joint_angles_from_axes(n, rot)


def joint_angles_from_axes(n: np.ndarray, rot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(universal, spherical) joint angles [..., 6] (rad) from unit leg axes n [..., 6, 3] and R [..., 3, 3].

    Args:
        n: unit leg axes n_i [..., 6, 3] (base frame).
        rot: platform rotation R [..., 3, 3].

    Returns:
        (universal, spherical), each [..., 6] (rad): arccos(n_i . e_z) and arccos(n_i . R e_z), the leg axis
        against the base and the platform z axis.
    """
    universal = np.arccos(np.clip(n[..., 2], -1.0, 1.0))
    platform_z = rot[..., :, 2]
    spherical = np.arccos(np.clip(np.einsum("...ij,...j->...i", n, platform_z), -1.0, 1.0))
    return universal, spherical
