"""Forward kinematics of the 6-UPS platform: strut lengths -> poses (batched Newton, numpy).

Solves g_i = |p + R a_i - b_i| - l_i = 0 with the analytic Jacobian,
updating the rotation on SO(3). One warm-started solve runs the same iteration on plain Python floats
(``fk_scalar``, low latency); large batches are split over the CPU cores.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ForwardKinematicsError, InvalidInputError
from ..input_checks import as_batch
from ..parallel import map_row_ranges
from ..robot import Robot, derived
from .fk_scalar import forward_kinematics_scalar
from .geometry import leg_vectors_from_rotation
from .jacobian import jacobian_from_vectors
from .limits import check_stroke
from .rotations import rotation_from_rpy, rpy_from_rotation, so3_exp


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
    """(leg lengths (6,), J^-1 (6, 6), sign of det J) at the home pose (cached per robot)."""

    def build():
        home = robot.home_pose
        rot = rotation_from_rpy(home[3:])
        d, r = leg_vectors_from_rotation(robot, home[:3], rot)
        lengths = np.linalg.norm(d, axis=-1)
        jac = jacobian_from_vectors(d, r, lengths)
        return lengths, np.linalg.inv(jac), np.sign(np.linalg.det(jac))

    return derived(robot, "fk_home", build)


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
    max|g| is halved (backtracking, up to 10 times). Without a guess the start is
    home + J0^-1 (l - l0). Solutions below the base or with det J of the other
    sign than at home (another assembly mode) are flagged assembly_ok=False.
    One sample with one guess is solved in plain floats (``fk_scalar``); large
    batches are split over the worker threads.

    Args:
        robot: the robot.
        lengths: strut lengths [..., 6] (m) as the encoders read them (``inverse_kinematics``): l_i minus
            ``robot.strut_zero_offsets``, all l_i > 0.
        guess: optional start poses [..., 6] = [x, y, z, roll, pitch, yaw] (m, rad, base frame), broadcast
            to the batch shape of ``lengths`` (warm start).
        tol: convergence threshold on max_i |g_i| (m).
        max_iter: most Newton iterations per sample.
        check_limits: check ``lengths`` against [stroke_min, stroke_max] before solving.

    Returns:
        ForwardKinematicsResult with pose [..., 6] (m, rad), rotation R [..., 3, 3], and per sample [...]:
        iterations, residual max_i |l_i(pose) - l_i| (m), converged and assembly_ok. Failures are flagged,
        not raised (see ``ForwardKinematicsResult.raise_for_failure``).

    Raises:
        InvalidInputError: ``lengths`` or ``guess`` is not numeric, not [..., 6] or not finite (``as_batch``),
            or a length is <= 0.
        StrokeLimitError: ``check_limits`` is set and a length is outside the stroke (``check_stroke``).
        ValueError: ``guess`` does not broadcast to the batch shape of ``lengths`` (numpy).
    """
    lengths = as_batch(lengths, 6, "lengths")
    if robot.strut_zero_offsets.any():  # encoder readings -> hinge-to-hinge lengths
        lengths = lengths + robot.strut_zero_offsets
    low, high = float(lengths.min()), float(lengths.max())
    if low <= 0:
        raise InvalidInputError("lengths: leg lengths must be > 0")
    lim = robot.limits
    if check_limits and (low < lim.stroke_min or high > lim.stroke_max):
        batch = lengths.reshape(-1, 6)
        check_stroke(batch, batch, lim)
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
    """(platform hinges, base hinges) as tuples of floats for the scalar solver (cached per robot)."""
    return derived(robot, "scalar_geometry", lambda: (
        tuple(map(tuple, robot.platform_hinges.tolist())),
        tuple(map(tuple, robot.base_hinges.tolist())),
    ))


def _forward_kinematics_single(robot, target, start, tol, max_iter, batch_shape) -> ForwardKinematicsResult:
    """Same Newton iteration as the batched path, for one warm-started solve (low latency)."""
    hinges, base = _scalar_geometry(robot)
    pose, rotation, iterations, res, assembly_ok = forward_kinematics_scalar(
        hinges, base, target.tolist(), start.tolist(), tol, max_iter, float(_home_cache(robot)[2])
    )
    return _fk_result(batch_shape, pose, rotation, iterations, res, res < tol, assembly_ok)
