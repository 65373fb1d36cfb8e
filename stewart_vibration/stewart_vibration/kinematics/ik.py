"""Inverse kinematics of the 6-UPS platform: poses -> strut lengths (batched numpy).

l_i = |p + R a_i - b_i| (paper eqs 4-5 in their general form), closed form. Small batches run
directly; large ones run through a cache-sized chunked path split over the CPU cores
(``parallel.map_row_ranges``). Every pose is checked against the robot's limits (``limits``).
"""

from __future__ import annotations

import numpy as np

from ..errors import UnreachablePoseError
from ..input_checks import as_batch
from ..parallel import map_row_ranges
from ..robot import Robot, derived
from .geometry import leg_vectors_from_rotation
from .jacobian import condition_number
from .limits import check_conditioning, check_reachable
from .rotations import rotation_from_rpy, rpy_matrix_entries


def inverse_kinematics(robot: Robot, poses, *, check_limits: bool = True) -> np.ndarray:
    """Closed-form inverse kinematics: leg lengths l_i = |d_i| of platform poses.

    Conditioning is not checked here (an SVD per pose): ``check_pose`` runs every check including
    SingularPoseError; use it for a pose from a user. Nothing is clipped.

    Args:
        robot: the robot.
        poses: platform poses [..., 6] = [x, y, z, roll, pitch, yaw] (m, rad), base frame.
        check_limits: check every pose with ``limits.check_reachable`` (default).

    Returns:
        Strut lengths [..., 6] (m) as the encoders read them: hinge-to-hinge lengths minus
        ``robot.strut_zero_offsets`` (the same for the drawing). The limits check the hinge-to-hinge lengths.

    Raises:
        InvalidInputError: a pose is not finite or not [..., 6].
        UnreachablePoseError, StrokeLimitError, JointLimitError: with ``check_limits``, naming the
            sample and the leg of the first violation.
    """
    poses = as_batch(poses, 6, "pose")
    flat = poses.reshape(-1, 6)
    if flat.shape[0] < 64:
        rot = rotation_from_rpy(poses[..., 3:])
        d, _ = leg_vectors_from_rotation(robot, poses[..., :3], rot)
        lengths = np.sqrt(np.einsum("...ij,...ij->...i", d, d))
        if check_limits:
            check_reachable(robot.limits, d, lengths, rot)
        return encoder_lengths(robot, lengths)
    lengths = np.empty_like(flat)
    starts = map_row_ranges(
        lambda start, stop: _ik_rows(robot, flat, lengths, start, stop, check_limits),
        flat.shape[0],
        align=_IK_CHUNK,
    )
    violated = min((s for s in starts if s is not None), default=None)
    if violated is not None:
        chunk = flat[violated : violated + _IK_CHUNK]
        rot = rotation_from_rpy(chunk[:, 3:])
        d, _ = leg_vectors_from_rotation(robot, chunk[:, :3], rot)
        try:
            check_reachable(robot.limits, d, np.linalg.norm(d, axis=-1), rot)
        except UnreachablePoseError as exc:
            exc.sample = (exc.sample or 0) + violated
            exc.args = (str(exc).replace(f"(sample {exc.sample - violated})", f"(sample {exc.sample})", 1),)
            raise
    return encoder_lengths(robot, lengths.reshape(poses.shape))


def encoder_lengths(robot: Robot, lengths: np.ndarray) -> np.ndarray:
    """What the strut encoders read (m) at hinge-to-hinge ``lengths`` [..., 6] (m): lengths - zero offsets."""
    offsets = robot.strut_zero_offsets
    return lengths - offsets if offsets.any() else lengths



_IK_CHUNK = 8192


def _ik_matrix(robot: Robot) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Constant maps of the chunked IK (cached per robot).

    With features F = [p_m R_mk (9), R_mk (9), p_m (3)] per pose (row-major R):
    W_len (6, 21) F = l_i^2 - |p|^2 - c_i (d_i = p - b_i + R a_i gives
    l_i^2 = |p|^2 + |a_i|^2 + |b_i|^2 + 2 p.R a_i - 2 b_i.R a_i - 2 p.b_i).
    W_chk (12, 9) R gives (R a_i)_z (rows 0-5) and -b_i . R e_z (rows 6-11),
    so d_i,z = (R a_i)_z + p_z - b_i,z and d_i . R e_z = p . R e_z - b_i . R e_z + a_i,z.
    Returns (W_len, c, W_chk, [-b_i,z ; a_i,z] (12,)).
    """

    def build():
        a, b = robot.platform_hinges, robot.base_hinges
        w_len = np.zeros((6, 21))
        w_chk = np.zeros((12, 9))
        for i in range(6):
            for m in range(3):
                for k in range(3):
                    w_len[i, 3 * m + k] = 2 * a[i, k]  # 2 p.R a_i
                    w_len[i, 9 + 3 * m + k] = -2 * b[i, m] * a[i, k]  # -2 b_i.R a_i
                w_len[i, 18 + m] = -2 * b[i, m]  # -2 p.b_i
                w_chk[i, 6 + m] = a[i, m]  # (R a_i)_z = R_2m a_i,m
                w_chk[6 + i, 3 * m + 2] = -b[i, m]  # -b_i . R e_z
        const = (a**2).sum(1) + (b**2).sum(1)
        return w_len, const, w_chk, np.concatenate([-b[:, 2], a[:, 2]])

    return derived(robot, "ik_matrix", build)


def _ik_rows(robot: Robot, poses: np.ndarray, out: np.ndarray, first: int, stop: int, check: bool):
    """Leg lengths into out[first:stop] (N, 6) for poses[first:stop] (N, 6) in
    cache-sized chunks; returns the start row of the first chunk with a limit
    violation (None if none or unchecked).

    Trigonometry dominates (scalar libm); for |angle| < 1.2 rad cos comes from
    sqrt(1 - sin^2) (cos > 0.36 there, so no precision loss).
    """
    w_len, const, w_chk, chk_const = _ik_matrix(robot)
    lim = robot.limits
    cos_u, cos_s = np.cos(lim.universal_joint_max), np.cos(lim.spherical_joint_max)
    feat, trig, tmp = np.empty((21, _IK_CHUNK)), np.empty((6, _IK_CHUNK)), np.empty(_IK_CHUNK)
    chk, bound = np.empty((12, _IK_CHUNK)), np.empty((6, _IK_CHUNK))
    for start in range(first, stop, _IK_CHUNK):
        q = poses[start : min(start + _IK_CHUNK, stop)].T
        m = q.shape[1]
        f, t, tt = feat[:, :m], trig[:, :m], tmp[:m]
        angles = q[3:]
        np.sin(angles, out=t[:3])
        if np.abs(angles).max() < 1.2:
            np.multiply(t[:3], t[:3], out=t[3:])
            np.subtract(1.0, t[3:], out=t[3:])
            np.sqrt(t[3:], out=t[3:])
        else:
            np.cos(angles, out=t[3:])
        rot = f[9:18]
        rpy_matrix_entries(*t, out=rot)  # type: ignore[misc]  # t has six rows: the six positional arguments
        for axis in range(3):
            np.multiply(rot[3 * axis : 3 * axis + 3], q[axis], out=f[3 * axis : 3 * axis + 3])
        f[18:21] = q[:3]
        sq = w_len @ f
        sq += const[:, None]
        np.einsum("km,km->m", q[:3], q[:3], out=tt)
        sq += tt
        np.sqrt(sq, out=sq)
        out[start : start + m] = sq.T
        if check:
            c = np.matmul(w_chk, rot, out=chk[:, :m])
            c += chk_const[:, None]
            c[:6] += q[2]  # d_i,z
            np.add(f[2], f[5], out=tt)
            tt += f[8]  # p . R e_z
            c[6:] += tt  # d_i . R e_z
            lim_u = np.multiply(sq, cos_u, out=bound[:, :m])
            bad = (
                (c[:6] <= 0.0).any()
                or sq.min() < lim.stroke_min
                or sq.max() > lim.stroke_max
                or (c[:6] < lim_u).any()
            )
            if not bad:
                lim_s = np.multiply(sq, cos_s, out=lim_u)
                bad = (c[6:] < lim_s).any()
            if bad:
                return start
    return None



def check_pose(robot: Robot, poses) -> np.ndarray:
    """Every check of a pose from a user: shape, finite, above the base, stroke, joints, conditioning.

    Args:
        robot: the robot.
        poses: platform poses [..., 6] (m, rad).

    Returns:
        Leg lengths [..., 6] (m), as ``inverse_kinematics``.

    Raises:
        InvalidInputError, UnreachablePoseError, StrokeLimitError, JointLimitError: as
            ``inverse_kinematics``.
        SingularPoseError: the Jacobian's condition number exceeds condition_number_max.
    """
    lengths = inverse_kinematics(robot, poses, check_limits=True)
    check_conditioning(robot.limits, condition_number(robot, poses))
    return lengths
