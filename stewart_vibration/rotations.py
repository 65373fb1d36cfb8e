"""Rotations: roll-pitch-yaw, rotation vectors, quaternions (batched, pure numpy).

Convention (paper eq. 3): R = Rz(yaw) Ry(pitch) Rx(roll), i.e. fixed-axis
rotations about x, then y, then z. Quaternions are ROS order [x, y, z, w].
"""

from __future__ import annotations

import numpy as np

from .errors import InvalidInputError
from .validation import as_batch


def rotation_from_rpy(rpy) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll) for rpy [..., 3] (rad) -> [..., 3, 3]."""
    rpy = np.asarray(rpy, dtype=float)
    cr, cp, cy = np.cos(rpy[..., 0]), np.cos(rpy[..., 1]), np.cos(rpy[..., 2])
    sr, sp, sy = np.sin(rpy[..., 0]), np.sin(rpy[..., 1]), np.sin(rpy[..., 2])
    rot = np.empty(rpy.shape[:-1] + (3, 3))
    rot[..., 0, 0] = cy * cp
    rot[..., 0, 1] = cy * sp * sr - sy * cr
    rot[..., 0, 2] = cy * sp * cr + sy * sr
    rot[..., 1, 0] = sy * cp
    rot[..., 1, 1] = sy * sp * sr + cy * cr
    rot[..., 1, 2] = sy * sp * cr - cy * sr
    rot[..., 2, 0] = -sp
    rot[..., 2, 1] = cp * sr
    rot[..., 2, 2] = cp * cr
    return rot


def rpy_from_rotation(rot) -> np.ndarray:
    """Inverse of rotation_from_rpy: [..., 3, 3] -> [..., 3] with pitch in [-pi/2, pi/2]."""
    rot = np.asarray(rot, dtype=float)
    pitch = np.arctan2(-rot[..., 2, 0], np.hypot(rot[..., 0, 0], rot[..., 1, 0]))
    roll = np.arctan2(rot[..., 2, 1], rot[..., 2, 2])
    yaw = np.arctan2(rot[..., 1, 0], rot[..., 0, 0])
    return np.stack([roll, pitch, yaw], axis=-1)


def euler_rate_matrix(rpy) -> np.ndarray:
    """E(theta) with w = E theta_dot (w in the base frame); singular at pitch = +-pi/2.

    E = [[cy cp, -sy, 0], [sy cp, cy, 0], [-sp, 0, 1]].
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
    """[v]x for v [..., 3] -> [..., 3, 3] so that skew(v) @ u = v x u."""
    v = np.asarray(v, dtype=float)
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def so3_exp(phi) -> np.ndarray:
    """Rodrigues: exp([phi]x) for rotation vectors phi [..., 3] (rad) -> [..., 3, 3]."""
    phi = np.asarray(phi, dtype=float)
    theta2 = np.einsum("...i,...i->...", phi, phi)
    theta = np.sqrt(theta2)
    small = theta2 < 1e-12
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - theta2 / 24.0, (1.0 - np.cos(safe)) / (safe * safe))
    k = skew(phi)
    return np.eye(3) + a[..., None, None] * k + b[..., None, None] * (k @ k)


def so3_log(rot) -> np.ndarray:
    """Rotation vector of R [..., 3, 3] (angle < pi) -> [..., 3]."""
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
    """Unit quaternion [x, y, z, w] of R = Rz(yaw) Ry(pitch) Rx(roll)."""
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
    """Rotation matrices [..., 3, 3] of unit quaternions [..., 4] [x, y, z, w] (not renormalised)."""
    q = np.asarray(quat, dtype=float)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def rpy_from_quaternion(quat, *, unit_tolerance: float = 1e-6) -> np.ndarray:
    """[x, y, z, w] -> [roll, pitch, yaw]. Rejects non-unit quaternions (|q| off by > tolerance)."""
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
    """Pose vectors [..., 6] -> (position [..., 3] m, quaternion [..., 4] [x, y, z, w])."""
    poses = as_batch(poses, 6, "pose")
    return poses[..., :3].copy(), quaternion_from_rpy(poses[..., 3:])


# Hand-typed and serialised quaternions are unit only to a few digits: like tf2, accept |q| within 1e-3
# of 1 (and normalise), refuse beyond.
MESSAGE_QUATERNION_TOLERANCE = 1e-3


def pose_from_position_quaternion(position, quaternion, *, unit_tolerance: float = 1e-6) -> np.ndarray:
    """(position [..., 3], unit quaternion [..., 4] [x, y, z, w]) -> pose vectors [..., 6]; the quaternion
    is normalised when its norm is within ``unit_tolerance`` of 1, refused (InvalidInputError) beyond."""
    position = as_batch(position, 3, "position")
    rpy = rpy_from_quaternion(quaternion, unit_tolerance=unit_tolerance)
    return np.concatenate(np.broadcast_arrays(position, rpy), axis=-1)
