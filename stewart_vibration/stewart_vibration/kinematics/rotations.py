"""Rotations: roll-pitch-yaw, rotation vectors, quaternions (batched, pure numpy).

Convention (paper eq. 3): R = Rz(yaw) Ry(pitch) Rx(roll), i.e. fixed-axis
rotations about x, then y, then z. Quaternions are ROS order [x, y, z, w].
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InvalidInputError
from ..input_checks import as_batch


def wrap_angle(angle):
    """Angle(s) (rad) wrapped to (-pi, pi]: pi stays pi, -pi becomes pi.

    Args:
        angle: angles (rad), a float or an array of any shape.

    Returns:
        The wrapped angles (rad), same shape as ``angle`` (a numpy scalar for a float).
    """
    return np.pi - (np.pi - np.asarray(angle)) % (2 * np.pi)

def rpy_matrix_entries(sr, sp, sy, cr, cp, cy, out=None):
    """The nine entries of R = Rz(yaw) Ry(pitch) Rx(roll), row-major, from the sines and cosines of
    roll, pitch and yaw: the one place the roll-pitch-yaw formula (paper eq. 3) is written.

    Works on floats (the scalar forward kinematics) and on arrays (the batched paths) alike.

    Args:
        sr, sp, sy: sin(roll), sin(pitch), sin(yaw) (floats or arrays of one shape).
        cr, cp, cy: the cosines.
        out: optional sequence of nine writable arrays to fill (the chunked inverse kinematics).

    Returns:
        The nine entries R_00, R_01, ..., R_22 (a tuple), or ``out`` filled with them.
    """
    if out is None:
        return (
            cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr,
            sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr,
            -sp, cp * sr, cp * cr,
        )
    # the same nine products written into the caller's rows without temporaries (the chunked inverse
    # kinematics runs at ~1e7 poses/s; expression temporaries cost a third of that)
    tmp = np.empty_like(out[0])
    np.multiply(cy, cp, out=out[0])
    np.multiply(cy * sp, sr, out=out[1])
    out[1] -= np.multiply(sy, cr, out=tmp)
    np.multiply(cy * sp, cr, out=out[2])
    out[2] += np.multiply(sy, sr, out=tmp)
    np.multiply(sy, cp, out=out[3])
    np.multiply(sy * sp, sr, out=out[4])
    out[4] += np.multiply(cy, cr, out=tmp)
    np.multiply(sy * sp, cr, out=out[5])
    out[5] -= np.multiply(cy, sr, out=tmp)
    np.negative(sp, out=out[6])
    np.multiply(cp, sr, out=out[7])
    np.multiply(cp, cr, out=out[8])
    return out


def rpy_from_matrix_entries(r00, r10, r20, r21, r22, atan2=np.arctan2, hypot=np.hypot):
    """(roll, pitch, yaw) of R = Rz(yaw) Ry(pitch) Rx(roll) from five of its entries, pitch in [-pi/2, pi/2].

    The one place the inverse formula is written; ``atan2`` and ``hypot`` are numpy's (arrays) or
    ``math``'s (floats, the scalar forward kinematics).

    Args:
        r00, r10, r20, r21, r22: the entries R_00, R_10, R_20, R_21, R_22 (floats or arrays of one shape).
        atan2: the two-argument arctangent to use (``np.arctan2`` or ``math.atan2``).
        hypot: the hypotenuse function to use (``np.hypot`` or ``math.hypot``).

    Returns:
        (roll, pitch, yaw) (rad), a tuple of floats or arrays: roll = atan2(R_21, R_22),
        pitch = atan2(-R_20, hypot(R_00, R_10)), yaw = atan2(R_10, R_00).
    """
    return atan2(r21, r22), atan2(-r20, hypot(r00, r10)), atan2(r10, r00)


def rotation_from_rpy(rpy) -> np.ndarray:
    """Rotation matrices of roll-pitch-yaw angles: R = Rz(yaw) Ry(pitch) Rx(roll) (paper eq. 3).

    Args:
        rpy: [..., 3] = [roll, pitch, yaw] (rad).

    Returns:
        R [..., 3, 3] (platform frame -> base frame).
    """
    rpy = np.asarray(rpy, dtype=float)
    entries = rpy_matrix_entries(*np.sin(np.moveaxis(rpy, -1, 0)), *np.cos(np.moveaxis(rpy, -1, 0)))
    rot = np.empty(rpy.shape[:-1] + (3, 3))
    for k, value in enumerate(entries):
        rot[..., k // 3, k % 3] = value
    return rot


def rpy_from_rotation(rot) -> np.ndarray:
    """Inverse of ``rotation_from_rpy``: R [..., 3, 3] -> [..., 3] (rad) with pitch in [-pi/2, pi/2].

    Args:
        rot: rotation matrices R [..., 3, 3] (platform frame -> base frame).

    Returns:
        [..., 3] = [roll, pitch, yaw] (rad), pitch in [-pi/2, pi/2].
    """
    rot = np.asarray(rot, dtype=float)
    return np.stack(rpy_from_matrix_entries(rot[..., 0, 0], rot[..., 1, 0], rot[..., 2, 0], rot[..., 2, 1],
                                            rot[..., 2, 2]), axis=-1)


def rotation_from_rpy_scalar(roll: float, pitch: float, yaw: float):
    """``rotation_from_rpy`` for one angle triple in plain floats (rad): R as nested tuples, rows first.

    Args:
        roll: roll angle (rad).
        pitch: pitch angle (rad).
        yaw: yaw angle (rad).

    Returns:
        R = Rz(yaw) Ry(pitch) Rx(roll) as three row tuples of three floats (platform frame -> base frame).
    """
    e = rpy_matrix_entries(math.sin(roll), math.sin(pitch), math.sin(yaw),
                           math.cos(roll), math.cos(pitch), math.cos(yaw))
    return (e[0], e[1], e[2]), (e[3], e[4], e[5]), (e[6], e[7], e[8])


def rpy_from_rotation_scalar(rot) -> tuple[float, float, float]:
    """``rpy_from_rotation`` for one rotation given as nested tuples (rows first), in plain floats.

    Args:
        rot: R as three rows of three floats (indexable as ``rot[row][col]``).

    Returns:
        (roll, pitch, yaw) as floats (rad), pitch in [-pi/2, pi/2].
    """
    return rpy_from_matrix_entries(rot[0][0], rot[1][0], rot[2][0], rot[2][1], rot[2][2], math.atan2, math.hypot)


def euler_rate_matrix(rpy) -> np.ndarray:
    """E(theta) with w = E theta_dot (w in the base frame); singular at pitch = +-pi/2.

    E = [[cy cp, -sy, 0], [sy cp, cy, 0], [-sp, 0, 1]].

    Args:
        rpy: [..., 3] = [roll, pitch, yaw] (rad); only pitch and yaw enter E.

    Returns:
        E [..., 3, 3], mapping roll-pitch-yaw rates (rad/s) to the angular velocity w (rad/s, base frame).
    """
    rpy = np.asarray(rpy, dtype=float)
    cp, cy = np.cos(rpy[..., 1]), np.cos(rpy[..., 2])
    sp, sy = np.sin(rpy[..., 1]), np.sin(rpy[..., 2])
    mat = np.zeros(rpy.shape[:-1] + (3, 3))
    mat[..., 0, 0] = cy * cp
    mat[..., 0, 1] = -sy
    mat[..., 1, 0] = sy * cp
    mat[..., 1, 1] = cy
    mat[..., 2, 0] = -sp
    mat[..., 2, 2] = 1.0
    return mat


def skew(v) -> np.ndarray:
    """[v]x for v [..., 3] -> [..., 3, 3] so that skew(v) @ u = v x u.

    Args:
        v: vectors [..., 3].

    Returns:
        The skew-symmetric matrices [v]x, [..., 3, 3].
    """
    v = np.asarray(v, dtype=float)
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def rodrigues_coefficients(theta2):
    """(sin t / t, (1 - cos t) / t^2) for t^2 = ``theta2`` (floats or arrays): the coefficients of
    exp([phi]x) = I + a [phi]x + b [phi]x^2, |phi| = t (Rodrigues' formula).

    b is evaluated as (sin(t/2) / t)^2 * 2, free of the cancellation in 1 - cos t, so micro-radian
    rotations keep full relative precision; below t^2 = 1e-12 the Taylor series is used.

    Args:
        theta2: squared rotation angle t^2 (rad^2), a float or an array of any shape.

    Returns:
        (a, b), arrays of the shape of ``theta2`` (0-d for a float).
    """
    small = np.asarray(theta2) < 1e-12
    t = np.sqrt(np.where(small, 1.0, theta2))
    half = np.sin(0.5 * t) / t
    a = np.where(small, 1.0 - theta2 / 6.0, np.sin(t) / t)
    b = np.where(small, 0.5 - theta2 / 24.0, 2.0 * half * half)
    return a, b


def rodrigues_coefficients_scalar(theta2: float) -> tuple[float, float]:
    """``rodrigues_coefficients`` for one float (the scalar forward kinematics).

    Args:
        theta2: squared rotation angle t^2 (rad^2).

    Returns:
        (a, b) = (sin t / t, (1 - cos t) / t^2) as floats; the Taylor series below t^2 = 1e-12.
    """
    if theta2 < 1e-12:
        return 1.0 - theta2 / 6.0, 0.5 - theta2 / 24.0
    t = math.sqrt(theta2)
    half = math.sin(0.5 * t) / t
    return math.sin(t) / t, 2.0 * half * half


def so3_exp(phi) -> np.ndarray:
    """Rotation matrices of rotation vectors (Rodrigues' formula): exp([phi]x).

    Args:
        phi: rotation vectors [..., 3] (rad; axis times angle).

    Returns:
        R [..., 3, 3].
    """
    phi = np.asarray(phi, dtype=float)
    a, b = rodrigues_coefficients(np.einsum("...i,...i->...", phi, phi))
    k = skew(phi)
    return np.eye(3) + a[..., None, None] * k + b[..., None, None] * (k @ k)


def so3_exp_scalar(phi, rot):
    """exp([phi]x) R for one rotation vector phi (rad, 3 floats) and R as nested tuples (rows first).

    Args:
        phi: rotation vector (x, y, z) (rad; axis times angle), three floats.
        rot: R as three rows of three floats.

    Returns:
        The product exp([phi]x) R as three row tuples of three floats.
    """
    x, y, z = phi
    a, b = rodrigues_coefficients_scalar(x * x + y * y + z * z)
    e = (
        (1.0 - b * (y * y + z * z), -a * z + b * x * y, a * y + b * x * z),
        (a * z + b * x * y, 1.0 - b * (x * x + z * z), -a * x + b * y * z),
        (-a * y + b * x * z, a * x + b * y * z, 1.0 - b * (x * x + y * y)),
    )
    m0, m1, m2 = rot
    return tuple(
        (
            ei[0] * m0[0] + ei[1] * m1[0] + ei[2] * m2[0],
            ei[0] * m0[1] + ei[1] * m1[1] + ei[2] * m2[1],
            ei[0] * m0[2] + ei[1] * m1[2] + ei[2] * m2[2],
        )
        for ei in e
    )


def so3_log(rot) -> np.ndarray:
    """Rotation vector of R [..., 3, 3] (angle < pi) -> [..., 3].

    Args:
        rot: rotation matrices R [..., 3, 3] with rotation angle < pi (the axis is lost at pi).

    Returns:
        Rotation vectors [..., 3] (rad; axis times angle) with exp([phi]x) = R.
    """
    rot = np.asarray(rot, dtype=float)
    cos = np.clip((np.trace(rot, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    theta = np.arccos(cos)
    vee = np.stack(
        [rot[..., 2, 1] - rot[..., 1, 2], rot[..., 0, 2] - rot[..., 2, 0], rot[..., 1, 0] - rot[..., 0, 1]],
        axis=-1,
    )
    sin = np.sin(theta)
    scale = np.where(theta < 1e-6, 0.5 + theta**2 / 12.0, theta / (2.0 * np.where(sin == 0, 1.0, sin)))
    return scale[..., None] * vee


def quaternion_from_rpy(rpy) -> np.ndarray:
    """Unit quaternion [x, y, z, w] of R = Rz(yaw) Ry(pitch) Rx(roll).

    Args:
        rpy: [..., 3] = [roll, pitch, yaw] (rad).

    Returns:
        Unit quaternions [..., 4] in ROS order [x, y, z, w].
    """
    rpy = np.asarray(rpy, dtype=float)
    hr, hp, hy = rpy[..., 0] / 2, rpy[..., 1] / 2, rpy[..., 2] / 2
    cr, sr, cp, sp, cy, sy = np.cos(hr), np.sin(hr), np.cos(hp), np.sin(hp), np.cos(hy), np.sin(hy)
    return np.stack(
        [
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy,
        ],
        axis=-1,
    )


def rotation_from_quaternion(quat) -> np.ndarray:
    """Rotation matrices [..., 3, 3] of unit quaternions [..., 4] [x, y, z, w] (not renormalised).

    Args:
        quat: unit quaternions [..., 4] in ROS order [x, y, z, w]; not normalised here.

    Returns:
        R [..., 3, 3].
    """
    q = np.asarray(quat, dtype=float)
    one = q.shape == (4,)  # one quaternion (a sensor's sample): Python floats, one array, no stacking
    x, y, z, w = (float(v) for v in q) if one else (q[..., 0], q[..., 1], q[..., 2], q[..., 3])
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    if one:
        return np.array(rows)
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def rpy_from_quaternion(quat, *, unit_tolerance: float = 1e-6) -> np.ndarray:
    """[x, y, z, w] -> [roll, pitch, yaw]. Rejects non-unit quaternions (|q| off by > tolerance).

    Args:
        quat: quaternions [..., 4] in ROS order [x, y, z, w]; normalised before conversion.
        unit_tolerance: largest accepted | |q| - 1 |.

    Returns:
        [..., 3] = [roll, pitch, yaw] (rad), pitch in [-pi/2, pi/2].

    Raises:
        InvalidInputError: ``quat`` is not numeric, not [..., 4] or not finite (``as_batch``), or a norm differs
            from 1 by more than ``unit_tolerance``.
    """
    q = as_batch(quat, 4, "quaternion")
    norm = np.linalg.norm(q, axis=-1)
    if (np.abs(norm - 1.0) > unit_tolerance).any():
        bad = float(norm.reshape(-1)[np.argmax(np.abs(norm.reshape(-1) - 1.0))])
        raise InvalidInputError(f"quaternion: not a unit quaternion (norm {bad:.6g})")
    x, y, z, w = np.moveaxis(q / norm[..., None], -1, 0)
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.stack([roll, pitch, yaw], axis=-1)


def pose_to_position_quaternion(poses) -> tuple[np.ndarray, np.ndarray]:
    """Pose vectors [..., 6] -> (position [..., 3] m, quaternion [..., 4] [x, y, z, w]).

    Args:
        poses: platform poses [..., 6] = [x, y, z, roll, pitch, yaw] (m, rad).

    Returns:
        (position [..., 3] (m, a copy), unit quaternion [..., 4] [x, y, z, w]).

    Raises:
        InvalidInputError: a pose is not numeric, not [..., 6] or not finite (``as_batch``).
    """
    poses = as_batch(poses, 6, "pose")
    return poses[..., :3].copy(), quaternion_from_rpy(poses[..., 3:])


# Hand-typed and serialised quaternions are unit only to a few digits: like tf2, accept |q| within 1e-3
# of 1 (and normalise), refuse beyond.
MESSAGE_QUATERNION_TOLERANCE = 1e-3


def pose_from_position_quaternion(position, quaternion, *, unit_tolerance: float = 1e-6) -> np.ndarray:
    """(position [..., 3], unit quaternion [..., 4] [x, y, z, w]) -> pose vectors [..., 6].

    The quaternion is normalised when its norm is within ``unit_tolerance`` of 1, refused beyond.

    Args:
        position: platform positions [..., 3] (m).
        quaternion: platform orientations [..., 4] [x, y, z, w]; broadcast against ``position``.
        unit_tolerance: largest accepted | |q| - 1 |.

    Returns:
        Poses [..., 6] = [x, y, z, roll, pitch, yaw] (m, rad) of the broadcast shape.

    Raises:
        InvalidInputError: ``position`` is not [..., 3] or not finite, ``quaternion`` is not [..., 4] or not
            finite, or a quaternion norm differs from 1 by more than ``unit_tolerance``.
        ValueError: the batch shapes of ``position`` and ``quaternion`` do not broadcast (numpy).
    """
    position = as_batch(position, 3, "position")
    rpy = rpy_from_quaternion(quaternion, unit_tolerance=unit_tolerance)
    return np.concatenate(np.broadcast_arrays(position, rpy), axis=-1)
