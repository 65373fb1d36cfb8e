"""Inverse and forward kinematics of the 6-UPS Stewart platform (batched numpy).

Notation (REVIEW.md, general form of eqs 4-11): b_i base hinge (base frame),
a_i platform hinge (platform frame), pose q = [x, y, z, roll, pitch, yaw]
with p = q[:3] and R = Rz(yaw) Ry(pitch) Rx(roll);
d_i = p + R a_i - b_i, l_i = |d_i|, n_i = d_i / l_i.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import (
    ForwardKinematicsError,
    InvalidInputError,
    JointLimitError,
    SingularPoseError,
    StrokeLimitError,
    UnreachablePoseError,
)
from .kinematics_scalar import forward_kinematics_scalar
from .parallel import map_row_ranges
from .robot import Robot
from .rotations import rotation_from_rpy, rpy_from_rotation, so3_exp
from .validation import as_batch, first_violation

# ---------------------------------------------------------------------------
# Inverse kinematics


def _hinge_map(robot: Robot) -> np.ndarray:
    """Constant (9, 18) matrix C with (R.reshape(9) @ C).reshape(6, 3) = R a_i (cached)."""
    cmap = getattr(robot, "_hinge_map", None)
    if cmap is None:
        cmap = np.zeros((9, 18))
        for leg, a in enumerate(robot.platform_hinges):
            for m in range(3):
                cmap[3 * m : 3 * m + 3, 3 * leg + m] = a
        object.__setattr__(robot, "_hinge_map", cmap)
    return cmap


def leg_vectors_from_rotation(robot: Robot, position: np.ndarray, rotation: np.ndarray):
    """(d [..., 6, 3], r = R a_i [..., 6, 3]) for p [..., 3] and R [..., 3, 3] (base frame, m).

    R a_i for all legs is one matrix product with a constant hinge matrix.
    """
    batch = rotation.shape[:-2]
    r = (rotation.reshape(batch + (9,)) @ _hinge_map(robot)).reshape(batch + (6, 3))
    d = r + (position[..., None, :] - robot.base_hinges)
    return d, r


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b over the last axis (faster than np.cross for small batches)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def leg_vectors(robot: Robot, poses) -> np.ndarray:
    """Leg vectors d_i = p + R a_i - b_i, [..., 6] poses -> [..., 6, 3] (base frame, m)."""
    poses = as_batch(poses, 6, "pose")
    return leg_vectors_from_rotation(robot, poses[..., :3], rotation_from_rpy(poses[..., 3:]))[0]


def inverse_kinematics(robot: Robot, poses, *, check_limits: bool = True) -> np.ndarray:
    """Closed-form IK: poses [..., 6] (m, rad) -> leg lengths l_i = |d_i| [..., 6] (m).

    With ``check_limits`` (default) raises StrokeLimitError / JointLimitError
    / UnreachablePoseError naming the sample and leg; nothing is clipped.
    Conditioning is not checked here (an SVD per pose): ``check_pose`` runs
    every check including SingularPoseError; use it for a pose from a user.
    Large batches run through a cache-sized chunked path (see _ik_rows),
    split over the CPU cores (parallel.map_row_ranges).
    """
    poses = as_batch(poses, 6, "pose")
    flat = poses.reshape(-1, 6)
    if flat.shape[0] < 64:
        rot = rotation_from_rpy(poses[..., 3:])
        d, _ = leg_vectors_from_rotation(robot, poses[..., :3], rot)
        lengths = np.sqrt(np.einsum("...ij,...ij->...i", d, d))
        if check_limits:
            _check_reachable(robot, d, lengths, rot)
        return lengths
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
            _check_reachable(robot, d, np.linalg.norm(d, axis=-1), rot)
        except UnreachablePoseError as exc:
            exc.sample = (exc.sample or 0) + violated
            exc.args = (str(exc).replace(f"(sample {exc.sample - violated})", f"(sample {exc.sample})", 1),)
            raise
    return lengths.reshape(poses.shape)


_IK_CHUNK = 8192


def _ik_matrix(robot: Robot) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Constant maps of the chunked IK, cached on the robot.

    With features F = [p_m R_mk (9), R_mk (9), p_m (3)] per pose (row-major R):
    W_len (6, 21) F = l_i^2 - |p|^2 - c_i (d_i = p - b_i + R a_i gives
    l_i^2 = |p|^2 + |a_i|^2 + |b_i|^2 + 2 p.R a_i - 2 b_i.R a_i - 2 p.b_i).
    W_chk (12, 9) R gives (R a_i)_z (rows 0-5) and -b_i . R e_z (rows 6-11),
    so d_i,z = (R a_i)_z + p_z - b_i,z and d_i . R e_z = p . R e_z - b_i . R e_z + a_i,z.
    Returns (W_len, c, W_chk, [-b_i,z ; a_i,z] (12,)).
    """
    cached = getattr(robot, "_ik_matrix", None)
    if cached is None:
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
        cached = (w_len, const, w_chk, np.concatenate([-b[:, 2], a[:, 2]]))
        object.__setattr__(robot, "_ik_matrix", cached)
    return cached


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
        sr, sp, sy, cr, cp, cy = t
        rot = f[9:18]
        np.multiply(cy, cp, out=rot[0])
        np.multiply(sy, cr, out=tt)
        np.multiply(cy * sp, sr, out=rot[1])
        rot[1] -= tt
        np.multiply(sy, sr, out=tt)
        np.multiply(cy * sp, cr, out=rot[2])
        rot[2] += tt
        np.multiply(sy, cp, out=rot[3])
        np.multiply(cy, cr, out=tt)
        np.multiply(sy * sp, sr, out=rot[4])
        rot[4] += tt
        np.multiply(cy, sr, out=tt)
        np.multiply(sy * sp, cr, out=rot[5])
        rot[5] -= tt
        np.negative(sp, out=rot[6])
        np.multiply(cp, sr, out=rot[7])
        np.multiply(cp, cr, out=rot[8])
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


def joint_angles(robot: Robot, poses) -> tuple[np.ndarray, np.ndarray]:
    """(universal, spherical) joint angles [..., 6] (rad): leg axis vs base z and vs platform z."""
    poses = as_batch(poses, 6, "pose")
    rot = rotation_from_rpy(poses[..., 3:])
    d, _ = leg_vectors_from_rotation(robot, poses[..., :3], rot)
    n = d / np.linalg.norm(d, axis=-1, keepdims=True)
    return _joint_angles_from_axes(n, rot)


def _joint_angles_from_axes(n: np.ndarray, rot: np.ndarray):
    universal = np.arccos(np.clip(n[..., 2], -1.0, 1.0))
    platform_z = rot[..., :, 2]
    spherical = np.arccos(np.clip(np.einsum("...ij,...j->...i", n, platform_z), -1.0, 1.0))
    return universal, spherical


def _check_reachable(robot: Robot, d: np.ndarray, lengths: np.ndarray, rot: np.ndarray) -> None:
    lim = robot.limits
    below = d[..., 2] <= 0.0
    if below.any():
        sample, leg = first_violation(below)
        raise UnreachablePoseError(
            f"unreachable pose (sample {sample}): platform hinge of leg {leg + 1} is not above "
            f"the base hinge plane (d_z = {d.reshape(-1, 6, 3)[sample, leg, 2]:.6g} m)",
            leg=leg + 1,
            sample=sample,
        )
    for mask, limit, word in (
        (lengths < lim.stroke_min, lim.stroke_min, "below the minimum"),
        (lengths > lim.stroke_max, lim.stroke_max, "above the maximum"),
    ):
        if mask.any():
            sample, leg = first_violation(mask)
            value = float(lengths.reshape(-1, 6)[sample, leg])
            raise StrokeLimitError(
                f"stroke limit (sample {sample}): leg {leg + 1} length {value:.6f} m is "
                f"{abs(value - limit) * 1e3:.3f} mm {word} stroke {limit:.6f} m",
                leg=leg + 1,
                sample=sample,
                value=value,
                limit=limit,
            )
    n = d / lengths[..., None]
    universal, spherical = _joint_angles_from_axes(n, rot)
    for angles, limit, name in (
        (universal, lim.universal_joint_max, "universal (base)"),
        (spherical, lim.spherical_joint_max, "spherical (platform)"),
    ):
        mask = angles > limit
        if mask.any():
            sample, leg = first_violation(mask)
            value = float(angles.reshape(-1, 6)[sample, leg])
            raise JointLimitError(
                f"joint limit (sample {sample}): {name} joint of leg {leg + 1} at "
                f"{np.degrees(value):.3f} deg exceeds {np.degrees(limit):.3f} deg by "
                f"{np.degrees(value - limit):.3f} deg",
                leg=leg + 1,
                sample=sample,
                value=value,
                limit=limit,
            )


# ---------------------------------------------------------------------------
# Jacobian and conditioning


def jacobian_from_vectors(d: np.ndarray, r: np.ndarray, lengths: np.ndarray | None = None):
    """Rows [n_i, (R a_i) x n_i] from leg vectors d and arms r = R a_i -> [..., 6, 6]."""
    if lengths is None:
        lengths = np.sqrt(np.einsum("...ij,...ij->...i", d, d))
    jac = np.empty(d.shape[:-1] + (6,))
    n = np.divide(d, lengths[..., None], out=jac[..., :3])
    jac[..., 3:] = cross(r, n)
    return jac


def jacobian(robot: Robot, poses) -> np.ndarray:
    """Leg-length Jacobian [..., 6, 6]: dl = J [dp; dphi].

    dp is the platform-origin displacement and dphi a small rotation vector,
    both in the base frame. J^T maps axial leg forces to the platform wrench
    (force, moment about the platform origin).
    """
    poses = as_batch(poses, 6, "pose")
    d, r = leg_vectors_from_rotation(robot, poses[..., :3], rotation_from_rpy(poses[..., 3:]))
    return jacobian_from_vectors(d, r)


def condition_number(robot: Robot, poses) -> np.ndarray:
    """Dimensionally homogeneous condition number of J [...].

    The rotation columns (m/rad) are divided by the characteristic length L
    (mean platform hinge radius) so all columns are dimensionless before the
    singular values are taken: J_h = J diag(1, 1, 1, 1/L, 1/L, 1/L).
    """
    jac = jacobian(robot, poses)
    scale = np.array([1.0, 1.0, 1.0] + [1.0 / robot.characteristic_length] * 3)
    sv = np.linalg.svd(jac * scale, compute_uv=False)
    with np.errstate(divide="ignore"):
        return sv[..., 0] / sv[..., -1]


def check_pose(robot: Robot, poses) -> np.ndarray:
    """Every pose check (shape, finite, above base, stroke, joints, conditioning); returns lengths."""
    lengths = inverse_kinematics(robot, poses, check_limits=True)
    cond = condition_number(robot, poses)
    bad = ~(cond <= robot.limits.condition_number_max)
    if bad.any():
        sample = int(np.argmax(bad.reshape(-1)))
        value = float(cond.reshape(-1)[sample])
        raise SingularPoseError(
            f"near-singular pose (sample {sample}): condition number {value:.4g} exceeds "
            f"{robot.limits.condition_number_max:.4g}",
            sample=sample,
            value=value,
            limit=robot.limits.condition_number_max,
        )
    return lengths


# ---------------------------------------------------------------------------
# Forward kinematics


@dataclass
class ForwardKinematicsResult:
    """Batched FK result. pose [..., 6]; rotation [..., 3, 3]; iterations, residual
    (max |l_i(pose) - l_i| in m), converged and assembly_ok [...]."""

    pose: np.ndarray
    rotation: np.ndarray
    iterations: np.ndarray
    residual: np.ndarray
    converged: np.ndarray
    assembly_ok: np.ndarray

    def raise_for_failure(self) -> None:
        """Raise ForwardKinematicsError if any sample failed, saying which and why."""
        failed = ~(self.converged & self.assembly_ok)
        if failed.any():
            flat = int(np.argmax(failed.reshape(-1)))
            if not self.assembly_ok.reshape(-1)[flat]:
                why = "the solution is in another assembly mode (below the base or mirrored)"
            else:
                why = f"no convergence (residual {self.residual.reshape(-1)[flat]:.3g} m)"
            raise ForwardKinematicsError(f"forward kinematics failed for sample {flat}: {why}")


def _home_cache(robot: Robot):
    cache = getattr(robot, "_fk_home_cache", None)
    if cache is None:
        home = robot.home_pose
        rot = rotation_from_rpy(home[3:])
        d, r = leg_vectors_from_rotation(robot, home[:3], rot)
        lengths = np.linalg.norm(d, axis=-1)
        jac = jacobian_from_vectors(d, r, lengths)
        cache = (lengths, np.linalg.inv(jac), np.sign(np.linalg.det(jac)))
        object.__setattr__(robot, "_fk_home_cache", cache)
    return cache


def forward_kinematics(
    robot: Robot,
    lengths,
    guess=None,
    tol: float = 1e-12,
    max_iter: int = 50,
    *,
    check_limits: bool = True,
) -> ForwardKinematicsResult:
    """Newton FK: leg lengths [..., 6] (m) -> ForwardKinematicsResult.

    Solves g_i = |p + R a_i - b_i| - l_i = 0 with the analytic Jacobian
    (J [dp; dphi] = -g, never inverted), updating p += dp and
    R <- exp([dphi]x) R, so no Euler-angle singularity. A step that increases
    max|g| is halved (backtracking, up to 10 times). ``guess`` (pose [..., 6])
    warm-starts; without it the start is home + J0^-1 (l - l0). Stops at
    max|g| < tol (m). Solutions below the base or with det J of the other
    sign than at home (another assembly mode) are flagged assembly_ok=False.
    """
    lengths = as_batch(lengths, 6, "lengths")
    low, high = float(lengths.min()), float(lengths.max())
    if low <= 0:
        raise InvalidInputError("lengths: leg lengths must be > 0")
    lim = robot.limits
    if check_limits and (low < lim.stroke_min or high > lim.stroke_max):
        for mask, limit in ((lengths < lim.stroke_min, lim.stroke_min), (lengths > lim.stroke_max, lim.stroke_max)):
            if mask.any():
                sample, leg = first_violation(mask)
                value = float(lengths.reshape(-1, 6)[sample, leg])
                raise StrokeLimitError(
                    f"stroke limit (sample {sample}): leg {leg + 1} length {value:.6f} m is "
                    f"{abs(value - limit) * 1e3:.3f} mm outside stroke limit {limit:.6f} m",
                    leg=leg + 1,
                    sample=sample,
                    value=value,
                    limit=limit,
                )
    batch_shape = lengths.shape[:-1]
    target = lengths.reshape(-1, 6)
    count = target.shape[0]
    home_lengths, home_jinv, _ = _home_cache(robot)
    if count == 1 and guess is not None:
        start = as_batch(guess, 6, "guess").reshape(-1, 6)
        if start.shape[0] == 1:
            return _forward_kinematics_single(robot, target[0], start[0], tol, max_iter, batch_shape)

    if guess is None:
        start = robot.home_pose + (target - home_lengths) @ home_jinv.T
    else:
        start = np.broadcast_to(as_batch(guess, 6, "guess"), batch_shape + (6,)).reshape(-1, 6)
    parts = map_row_ranges(
        lambda first, stop: _newton_rows(robot, target[first:stop], start[first:stop], tol, max_iter),
        count,
        min_rows=4096,
    )
    return _fk_result(batch_shape, *(np.concatenate(field) for field in zip(*parts)))


def _fk_result(batch_shape, pose, rotation, iterations, residual, converged, assembly_ok) -> ForwardKinematicsResult:
    """Flat per-sample FK outputs (arrays or scalars) reshaped to the caller's batch shape."""
    return ForwardKinematicsResult(
        pose=np.asarray(pose).reshape(batch_shape + (6,)),
        rotation=np.asarray(rotation).reshape(batch_shape + (3, 3)),
        iterations=np.asarray(iterations).reshape(batch_shape),
        residual=np.asarray(residual).reshape(batch_shape),
        converged=np.asarray(converged).reshape(batch_shape),
        assembly_ok=np.asarray(assembly_ok).reshape(batch_shape),
    )


def _newton_rows(robot: Robot, target: np.ndarray, start: np.ndarray, tol: float, max_iter: int):
    """Batched Newton for target lengths (N, 6) from start poses (N, 6): flat
    (pose, rotation, iterations, residual, converged, assembly_ok)."""
    count = target.shape[0]
    home_det_sign = _home_cache(robot)[2]
    position = start[:, :3].copy()
    rotation = rotation_from_rpy(start[:, 3:])

    d, r = leg_vectors_from_rotation(robot, position, rotation)
    current = np.sqrt(np.einsum("nij,nij->ni", d, d))
    g = current - target
    res = np.abs(g).max(axis=-1)
    iterations = np.zeros(count, dtype=int)
    active = np.flatnonzero(~(res < tol))
    for _ in range(max_iter):
        if active.size == 0:
            break
        # views while every sample is still iterating, gathers once some converged
        sel = slice(None) if active.size == count else active
        jac = jacobian_from_vectors(d[sel], r[sel], current[sel])
        step = _solve_steps(jac, -g[sel])
        alpha = np.ones(active.size)
        pending = np.arange(active.size)
        for halving in range(11):
            idx = sel if pending.size == count else active[pending]
            a = alpha[:, None] if pending.size == count else alpha[pending, None]
            s = step if pending.size == count else step[pending]
            p_try = position[idx] + a * s[:, :3]
            rot_try = so3_exp(a * s[:, 3:]) @ rotation[idx]
            d_try, r_try = leg_vectors_from_rotation(robot, p_try, rot_try)
            cur_try = np.sqrt(np.einsum("nij,nij->ni", d_try, d_try))
            g_try = cur_try - target[idx]
            res_try = np.abs(g_try).max(axis=-1)
            accept = (res_try < res[idx]) | (res_try < tol) | (halving == 10)
            if accept.all():
                position[idx], rotation[idx] = p_try, rot_try
                d[idx], r[idx], current[idx], g[idx], res[idx] = d_try, r_try, cur_try, g_try, res_try
                break
            ok = (np.arange(count) if isinstance(idx, slice) else idx)[accept]
            position[ok], rotation[ok] = p_try[accept], rot_try[accept]
            d[ok], r[ok], current[ok] = d_try[accept], r_try[accept], cur_try[accept]
            g[ok], res[ok] = g_try[accept], res_try[accept]
            pending = pending[~accept]
            alpha[pending] *= 0.5
        iterations[active] += 1
        active = active[~(res[active] < tol)]

    converged = res < tol
    jac_all = jacobian_from_vectors(d, r, current)
    det_sign = np.sign(np.linalg.det(jac_all))
    assembly_ok = (d[..., 2] > 0).all(axis=-1) & (det_sign == home_det_sign)
    pose = np.concatenate([position, rpy_from_rotation(rotation)], axis=-1)
    return pose, rotation, iterations, res, converged, assembly_ok


def _solve_steps(jac: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Newton steps J x = rhs for a batch; least squares if some J is singular."""
    try:
        return np.linalg.solve(jac, rhs[..., None])[..., 0]
    except np.linalg.LinAlgError:
        return np.einsum("nij,nj->ni", np.linalg.pinv(jac), rhs)


def _scalar_geometry(robot: Robot):
    """(platform hinges, base hinges) as tuples of floats for the scalar solver (cached)."""
    cached = getattr(robot, "_scalar_geometry", None)
    if cached is None:
        cached = (
            tuple(map(tuple, robot.platform_hinges.tolist())),
            tuple(map(tuple, robot.base_hinges.tolist())),
        )
        object.__setattr__(robot, "_scalar_geometry", cached)
    return cached


def _forward_kinematics_single(robot, target, start, tol, max_iter, batch_shape) -> ForwardKinematicsResult:
    """Same Newton iteration as the batched path, for one warm-started solve (low latency)."""
    hinges, base = _scalar_geometry(robot)
    pose, rotation, iterations, res, assembly_ok = forward_kinematics_scalar(
        hinges, base, target.tolist(), start.tolist(), tol, max_iter, float(_home_cache(robot)[2])
    )
    return _fk_result(batch_shape, pose, rotation, iterations, res, res < tol, assembly_ok)
