"""The leg-length Jacobian and its dimensionally homogeneous condition number (batched numpy).

Rows [n_i, (R a_i) x n_i] (the paper's eq. 11, corrected): dl = J [dp; dphi] with dp the
displacement of the platform origin and dphi a small rotation vector, both in the base frame; J^T maps
axial leg forces to the platform wrench (force, moment about the platform origin).
"""

from __future__ import annotations

import numpy as np

from ..input_checks import as_batch
from ..robot import Robot
from .geometry import cross, leg_vectors_from_rotation
from .rotations import rotation_from_rpy


def jacobian_from_vectors(d: np.ndarray, r: np.ndarray, lengths: np.ndarray | None = None) -> np.ndarray:
    """Jacobian rows [n_i, r_i x n_i] from leg vectors and hinge arms.

    Args:
        d: leg vectors d_i [..., 6, 3] (base frame, m).
        r: hinge arms r_i = R a_i [..., 6, 3] (base frame, m).
        lengths: |d_i| [..., 6] if already computed.

    Returns:
        J [..., 6, 6].
    """
    if lengths is None:
        lengths = np.sqrt(np.einsum("...ij,...ij->...i", d, d))
    jac = np.empty(d.shape[:-1] + (6,))
    n = np.divide(d, lengths[..., None], out=jac[..., :3])
    jac[..., 3:] = cross(r, n)
    return jac


def jacobian(robot: Robot, poses) -> np.ndarray:
    """Leg-length Jacobian J [..., 6, 6] at platform poses [..., 6] (m, rad): dl = J [dp; dphi].

    Args:
        robot: the robot.
        poses: platform poses [..., 6] = [x, y, z, roll, pitch, yaw] (m, rad).

    Returns:
        J [..., 6, 6] with rows [n_i, (R a_i) x n_i] (base frame); dp in m, dphi a small rotation vector (rad).

    Raises:
        InvalidInputError: a pose is not finite or not [..., 6].
    """
    poses = as_batch(poses, 6, "pose")
    d, r = leg_vectors_from_rotation(robot, poses[..., :3], rotation_from_rpy(poses[..., 3:]))
    return jacobian_from_vectors(d, r)


def condition_number(robot: Robot, poses) -> np.ndarray:
    """Dimensionally homogeneous condition number of J at poses [..., 6] -> [...].

    The rotation columns (m/rad) are divided by the characteristic length L (mean platform hinge
    radius) so all columns are dimensionless before the singular values are taken:
    J_h = J diag(1, 1, 1, 1/L, 1/L, 1/L).

    Args:
        robot: the robot (its ``characteristic_length`` L, m).
        poses: platform poses [..., 6] (m, rad).

    Returns:
        sigma_max / sigma_min of J_h, [...] (dimensionless, >= 1); inf at singular poses.

    Raises:
        InvalidInputError: a pose is not finite or not [..., 6].
    """
    jac = jacobian(robot, poses)
    scale = np.array([1.0, 1.0, 1.0] + [1.0 / robot.characteristic_length] * 3)
    sv = np.linalg.svd(jac * scale, compute_uv=False)
    with np.errstate(divide="ignore"):
        return sv[..., 0] / sv[..., -1]
