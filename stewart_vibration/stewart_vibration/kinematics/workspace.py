"""What the six struts do together along a path of strut lengths (batched numpy): the platform poses by
forward kinematics, warm-started along the path, and every pose limit at them -- platform hinges above the
base, universal and spherical joint angles, the Jacobian's condition number, FK converged -- on a grid fine
enough that nothing slips between the samples.

Every strut command is checked per strut (stroke, velocity, acceleration: ``emulation.strut_trajectory``);
a command legal per strut can still drive the platform out of its workspace together (+45 / -30 mm
alternating). ``check_strut_path`` is the one check of that, for the emulator's command acceptance and for
the kinematics node's planned moves.

The grid. The path l(t) is sampled on a sub-grid (SUBGRID_S); between two sub-grid points h apart every
strut stays within |chord| + a_max h^2 / 8 of the first one (a_max: strut_acceleration_max, which the path
keeps -- the per-strut check enforces it), so the cumulative sum C of these bounds bounds the strut travel
(infinity norm) between any two times. The checked samples are taken where C crosses multiples of
PATH_SPACING_M / 2 (sub-intervals longer than that are split first), so every instant of the path lies
within D / 2 <= PATH_SPACING_M / 2 of a checked sample, D the bound between its two neighbours. A pose
quantity q (joint angle, d_z, condition number) changes over a strut change of |dl|_inf <= h by at most
MARGIN_SAFETY h sum_j |dq / dl_j| plus a second-order allowance: the sensitivities are exact to first order
at the sample (``_sensitivity``: dq / dx from the leg geometry times J^-1, one batched solve; for the condition
number Weyl's bound on the singular values, or central differences near its limit), the allowance is the
square of a Lipschitz bound from the Jacobian's smallest singular value (``_PoseState.margins``; measured
against FK in the tests). The vibration units ride on the struts: the real hinge-to-hinge lengths stray up to
their amplitude_max (the ``reach``) from the path, so each sample must keep q plus its margin for h = D / 2 +
reach within the limit (the reach alone costs 0.1-0.3 deg of joint angle near the joint limits). Where the
spacing's share of that margin does not fit, the neighbouring intervals are resampled finer, as much finer as
it needs (up to MAX_REFINE times per round, REFINE_ROUNDS rounds), so a path is refused only where the reach
crosses the limit or within a few 1e-6 deg of that (the message names the margin).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np

from ..errors import ForwardKinematicsError, JointLimitError, SingularPoseError, UnreachablePoseError
from ..robot import Robot
from .fk import ForwardKinematicsResult, forward_kinematics
from .geometry import cross, joint_angles_from_axes, leg_vectors_from_rotation
from .jacobian import condition_number, jacobian_from_vectors
from .limits import check_stroke
from .rotations import rotation_from_rpy, rpy_from_rotation, so3_exp

PATH_SPACING_M = 2.5e-4  # bound on the strut travel between two neighbouring checked samples (m)
SUBGRID_S = 0.01  # time step of the sub-grid that bounds the travel (s)
MAX_SUBGRID = 200_000  # the sub-grid step grows beyond this many points (very long paths)
MAX_PATH_SAMPLES = 20_000  # a path needing more checked samples is refused (what one check may cost)
MAX_REFINE = 64  # largest subdivision of an interval near a limit, per round
REFINE_ROUNDS = 6  # rounds of subdivision near a limit
MAX_REFINE_SAMPLES = 1000  # new samples per round (the earliest intervals first)
ANCHOR_TRAVEL_M = 5e-3  # strut travel between the sequential warm-start anchors of the FK (m)
FK_RESIDUAL_M = 1e-9  # the FK of every sample must reproduce its lengths this closely (m)
FK_ITERATIONS = 15  # Newton from a warm start this close converges in < 6 iterations where a pose exists
FK_TOLERANCE_M = 1e-11  # Newton stops here (1e-12, the default, costs extra iterations at round-off)
COND_EXACT_ABOVE = 0.2  # above this fraction of condition_number_max its margin comes from measured derivatives
COND_STEP_M = 1e-6  # strut step of those central differences (m)
MARGIN_SAFETY = 1.1  # on the exact first-order changes (the second-order allowance comes on top)


@dataclass(frozen=True)
class PathPoses:
    """The checked samples of a path: times [n] (s), strut lengths [n, 6] (m), platform poses [n, 6]
    (m, rad, base frame) and condition numbers [n]."""

    times: np.ndarray
    lengths: np.ndarray
    poses: np.ndarray
    condition: np.ndarray


def check_strut_path(robot: Robot, sample_lengths, start: float, end: float, *, knots=None,
                     start_pose=None, what: str = "the path", reach: float | None = None) -> PathPoses:
    """Check what the six struts do together along l(t), t in [start, end]: raise the first violation in time.

    Args:
        robot: the robot (limits, geometry).
        sample_lengths: l(times [n]) -> strut lengths [n, 6] (m); a path with continuous velocity whose
            acceleration stays within strut_acceleration_max (checked per strut before).
        start, end: the span to check (s), start <= end.
        knots: optional times (s) where the path changes segment (sampled exactly; acceleration may jump there).
        start_pose: a pose near the one at ``start`` (m, rad): the FK's warm start (default home); the
            poses follow the path continuously from there.
        what: what the path is, for the messages ("the trajectory", "the reset move").
        reach: how far (m) the hinge-to-hinge lengths may stray from the path besides it: every limit must hold
            that far around it too. Default: the vibration unit's amplitude_max (the units ride on the struts).

    Returns:
        PathPoses of the checked samples.

    Raises:
        StrokeLimitError: a strut leaves the stroke (on the sub-grid).
        UnreachablePoseError: ``limit_name`` "hinge_above_base" (a platform hinge not above the base hinge plane),
            "forward_kinematics" (no converged FK, another assembly mode or a jump of the pose: near a
            singularity) or "max_path_samples" (the path is too long to check, > MAX_PATH_SAMPLES samples).
        JointLimitError: ``limit_name`` "universal_joint_max" / "spherical_joint_max".
        SingularPoseError: ``limit_name`` "condition_number_max".
        Each with ``time`` (s), ``leg`` (1..6 where one applies), ``value`` and ``limit``.
    """
    lim = robot.limits
    reach = robot.vibration_unit.amplitude_max if reach is None else float(reach)
    times, lengths, bound = _subgrid(robot, sample_lengths, float(start), float(end), knots, what)
    check_stroke(lengths, lengths, lim, what=f"length along {what}")
    cumulative = np.concatenate([[0.0], np.cumsum(bound)])
    picks = np.flatnonzero(np.diff(np.floor(cumulative / (0.5 * PATH_SPACING_M)), prepend=-1.0) > 0)
    picks = np.union1d(picks, [0, times.size - 1])
    _check_count(picks.size, f"{what} needs {picks.size} workspace samples (its struts may travel "
                 f"{cumulative[-1]:.3f} m)", float(start))
    t, lens, travel = times[picks], lengths[picks], np.diff(cumulative[picks])
    poses, failure = _poses_along(robot, t, lens, cumulative[picks], start_pose, what)
    if not len(poses):
        raise cast(UnreachablePoseError, failure)
    path = _Samples(t[:len(poses)], lens[:len(poses)], poses, travel[:len(poses) - 1], _PoseState.at(robot, poses))
    try:
        _check_jumps(path.state, path.travel, path.t, what)
    except UnreachablePoseError as jump:
        failure = failure if failure is not None and failure.time < jump.time else jump
        path.cut(robot, int(np.searchsorted(path.t, jump.time)))
    for _ in range(REFINE_ROUNDS):
        hard = np.flatnonzero(path.state.slack(robot, np.full(len(path.t), reach)) < 0)
        if hard.size:  # a sample beyond a limit: only what comes before it can hold an earlier violation
            path.cut(robot, int(hard[0]) + 1)
            failure = None
        failing = np.flatnonzero(path.state.slack(robot, _half(path.travel) + reach) < 0)
        if not failing.size or (hard.size and failing[0] == len(path.t) - 1):
            break  # nothing left to prove, or the first failure is a sample beyond the limit
        # where the margin does not fit: resample the neighbouring intervals finer
        if not _refine(robot, sample_lengths, path, failing[:np.searchsorted(failing, len(path.t) - 1)] if hard.size
                       else failing, what, reach):
            break
    slack = path.state.slack(robot, _half(path.travel) + reach)
    if (slack < 0).any():
        first = int(np.argmax(slack < 0))
        path.state.raise_violation(robot, first, _half(path.travel) + reach, float(path.t[first]), what)
    if failure is not None:
        raise failure
    return PathPoses(path.t, path.lengths, path.poses, path.state.condition)


@dataclass
class _Samples:
    """The checked samples of a path: times [n] (s), lengths and poses [n, 6], the travel bound of each interval
    [n - 1] (m) and the pose quantities."""

    t: np.ndarray
    lengths: np.ndarray
    poses: np.ndarray
    travel: np.ndarray
    state: _PoseState

    def cut(self, robot: Robot, keep: int) -> None:
        """Keep the first ``keep`` samples."""
        self.t, self.lengths, self.poses = self.t[:keep], self.lengths[:keep], self.poses[:keep]
        self.travel = self.travel[:max(keep - 1, 0)]
        self.state = _PoseState.at(robot, self.poses)


def _half(travel):
    """Per sample [n]: half the larger travel bound of its two intervals [n - 1] (m): how far the path strays
    from it (the nearer sample of every instant)."""
    return 0.5 * np.maximum(np.concatenate([travel, [0.0]]), np.concatenate([[0.0], travel]))


def _check_count(count: int, text: str, time: float) -> None:
    if count > MAX_PATH_SAMPLES:
        raise UnreachablePoseError(f"{text}; at most {MAX_PATH_SAMPLES}: send shorter trajectories",
                                   limit_name="max_path_samples", value=float(count), limit=float(MAX_PATH_SAMPLES),
                                   time=time)


def _subgrid(robot: Robot, sample_lengths, start: float, end: float, knots, what: str):
    """(times [m], lengths [m, 6], travel bound of each sub-interval [m - 1]) with every bound <= PATH_SPACING_M / 2.

    Raises UnreachablePoseError "max_path_samples" when the path needs more than MAX_PATH_SAMPLES checked samples
    (from the first sub-grid already: before any FK)."""
    a_max = robot.limits.strut_acceleration_max
    span = max(end - start, 0.0)
    step = max(SUBGRID_S, span / MAX_SUBGRID)
    count = int(np.ceil(span / step)) if span > 0 else 0
    grid: list[np.ndarray] = [start + step * np.arange(count), np.array([end])]
    if knots is not None:
        k = np.asarray(knots, dtype=float)
        grid.append(k[(k > start) & (k < end)])
    times = np.unique(np.concatenate(grid))
    lengths = np.asarray(sample_lengths(times), dtype=float)
    if not np.isfinite(lengths).all():
        raise UnreachablePoseError("non-finite strut lengths along the path", limit_name="forward_kinematics",
                                   time=float(times[np.argmax(~np.isfinite(lengths).all(axis=1))]))
    bound = _travel_bounds(times, lengths, a_max)
    needed = int(bound.sum() / (0.5 * PATH_SPACING_M)) + 2
    _check_count(needed, f"{what} needs {needed} workspace samples (its struts may travel {bound.sum():.3f} m)",
                 start)
    split = np.ceil(bound / (0.5 * PATH_SPACING_M)).astype(int)
    if (split > 1).any():  # fast sub-intervals: split each into `split` equal steps, sample once more
        pieces = np.maximum(split, 1)
        interval = np.repeat(np.arange(len(bound)), pieces)
        frac = (np.arange(int(pieces.sum())) - np.repeat(np.cumsum(pieces) - pieces, pieces)) / pieces[interval]
        times = np.concatenate([times[interval] + np.diff(times)[interval] * frac, times[-1:]])
        lengths = np.asarray(sample_lengths(times), dtype=float)
        bound = _travel_bounds(times, lengths, a_max)
    return times, lengths, bound


def _travel_bounds(times, lengths, a_max):
    """max over struts of |chord| + a_max h^2 / 8 per sub-interval: how far a strut can be from the interval's
    ends (its path deviates from the chord by at most a_max h^2 / 8)."""
    h = np.diff(times)
    return np.abs(np.diff(lengths, axis=0)).max(axis=1) + a_max * h * h / 8.0


def _poses_along(robot: Robot, times, lengths, travel, start_pose, what):
    """FK of every sample, warm-started along the path: sequential anchors ANCHOR_TRAVEL_M apart (each from the
    previous one), then one batched solve of the rest from the anchors' poses interpolated in travel.

    Returns (poses [k, 6] of the samples before the first whose FK fails, that failure as an
    UnreachablePoseError or None)."""
    guess = np.asarray(robot.home_pose if start_pose is None else start_pose, dtype=float)
    anchors = np.flatnonzero(np.diff(np.floor(travel / ANCHOR_TRAVEL_M), prepend=-1.0) > 0)
    anchors = np.union1d(anchors, [0, len(times) - 1])
    anchor_poses = np.empty((anchors.size, 6))
    failure, solved = None, anchors.size
    for j, index in enumerate(anchors):
        fk = _solve(robot, lengths[index], guess)
        failure = _fk_failure(fk, float(times[index]), what)
        if failure is not None:
            solved = j
            break
        guess = anchor_poses[j] = fk.pose
    count = len(times) if failure is None else int(anchors[solved])
    anchors, anchor_poses = anchors[:solved], anchor_poses[:solved]
    beyond = np.flatnonzero(_beyond_a_joint_limit(robot, anchor_poses))
    if len(beyond):  # an anchor past a limit: the samples after it cannot hold the first violation
        count, failure = int(anchors[beyond[0]]) + 1, None
        anchors, anchor_poses = anchors[:beyond[0] + 1], anchor_poses[:beyond[0] + 1]
    poses = np.empty((count, 6))
    poses[anchors[anchors < count]] = anchor_poses[anchors < count]
    rest = np.setdiff1d(np.arange(count), anchors)
    if rest.size:
        guesses = np.stack([np.interp(travel[rest], travel[anchors], anchor_poses[:, k]) for k in range(6)], axis=1)
        fk = _solve(robot, lengths[rest], guesses)
        bad = ~(fk.converged & fk.assembly_ok & (fk.residual <= FK_RESIDUAL_M))
        poses[rest] = fk.pose
        if bad.any():
            first = int(np.argmax(bad))
            failure = _fk_failure(fk_row(fk, first), float(times[rest][first]), what)
            poses = poses[:rest[first]]
    return poses, failure


def _beyond_a_joint_limit(robot: Robot, poses) -> np.ndarray:
    """[n]: a joint of the pose past its limit outright (no margin; the quick test of the FK anchors)."""
    if not len(poses):
        return np.zeros(0, dtype=bool)
    rot = rotation_from_rpy(poses[:, 3:])
    d, _ = leg_vectors_from_rotation(robot, poses[:, :3], rot)
    universal, spherical = joint_angles_from_axes(d / np.linalg.norm(d, axis=-1, keepdims=True), rot)
    lim = robot.limits
    beyond = (universal > lim.universal_joint_max).any(axis=1) | (spherical > lim.spherical_joint_max).any(axis=1)
    return np.asarray(beyond)


def _solve(robot: Robot, lengths, guess):
    """Warm-started FK of strut lengths [..., 6] (no stroke check: the sub-grid had it)."""
    return forward_kinematics(robot, lengths, guess=guess, check_limits=False, max_iter=FK_ITERATIONS,
                              tol=FK_TOLERANCE_M)


def fk_row(fk, index: int):
    """One row of a batched ForwardKinematicsResult, as a result of its own."""
    return ForwardKinematicsResult(*(np.asarray(getattr(fk, f))[index] for f in
                                     ("pose", "rotation", "iterations", "residual", "converged", "assembly_ok")))


def _fk_failure(fk, time: float, what: str) -> UnreachablePoseError | None:
    """The refusal of a failed FK solve at ``time`` (s), or None when it converged in the home assembly mode."""
    try:
        fk.raise_for_failure()
        residual = float(np.max(fk.residual))
        if not residual <= FK_RESIDUAL_M:
            raise ForwardKinematicsError(f"residual {residual:.3g} m")
    except ForwardKinematicsError as exc:
        return UnreachablePoseError(
            f"workspace limit at t = {time:.4f} s: {what} has no platform pose there ({exc}): near a "
            f"singularity or outside the workspace", limit_name="forward_kinematics", time=time)
    return None


@dataclass
class _PoseState:
    """Pose quantities at samples [n] with what the margins need: the joint angles' and d_z's exact first-order
    sensitivities to the strut lengths (``gradients``) and the Jacobian's singular values."""

    d: np.ndarray  # leg vectors [n, 6, 3]
    length: np.ndarray  # [n, 6]
    universal: np.ndarray  # [n, 6] rad
    spherical: np.ndarray  # [n, 6] rad
    condition: np.ndarray  # [n]
    sigma: np.ndarray  # singular values of J_h [n, 6], descending
    poses: np.ndarray
    sensitivity: np.ndarray  # [n, 3, 6]: sum over struts of |d q / d l_j| for q = d_z, universal, spherical (per leg)
    cond_terms: np.ndarray  # [n, 2]: sum over struts of |d cond / d l_j| and |d2 cond / d l_j^2| (NaN: not computed)

    @classmethod
    def at(cls, robot: Robot, poses: np.ndarray) -> _PoseState:
        rot = rotation_from_rpy(poses[:, 3:])
        d, r = leg_vectors_from_rotation(robot, poses[:, :3], rot)
        length = np.sqrt(np.einsum("nij,nij->ni", d, d))
        axes = d / length[..., None]
        universal, spherical = joint_angles_from_axes(axes, rot)
        jac = jacobian_from_vectors(d, r, length)
        sigma = np.linalg.svd(jac * np.r_[1.0, 1.0, 1.0, [1.0 / robot.characteristic_length] * 3], compute_uv=False)
        with np.errstate(divide="ignore"):
            condition = sigma[:, 0] / sigma[:, -1]
        return cls(d, length, universal, spherical, condition, sigma, poses,
                   _sensitivity(jac, r, axes, length, rot, universal, spherical),
                   _condition_terms(robot, poses, rot, jac, condition))

    def margins(self, robot: Robot, half):
        """How far d_z [n, 6] (m), the joint angles [n, 6] (rad) and the condition number [n] can move while every
        strut changes by at most ``half`` [n] (m): MARGIN_SAFETY times the exact first-order change (the
        sensitivities' row sums times ``half``) plus a second-order allowance (the Lipschitz bound below,
        squared, in the quantity's unit); for the condition number Weyl's bound on the singular values, or
        where it is above COND_EXACT_ABOVE of its limit its measured first and second derivatives."""
        arm = float(np.linalg.norm(robot.platform_hinges, axis=1).max())
        scale = robot.characteristic_length
        with np.errstate(divide="ignore", invalid="ignore"):
            pose_h = np.sqrt(6.0) * half / self.sigma[:, -1]  # |(dp, L dphi)|_2
            hinge = np.sqrt(1.0 + (arm / scale) ** 2) * pose_h  # |d d_i|
            turn = pose_h / scale  # |d phi|
            axis = hinge[:, None] / self.length  # |d n_i|
            row = axis + (arm / scale) * (turn[:, None] + axis)  # |d J_h row i|
            jac = np.sqrt(6.0) * row.max(axis=1)
            s1, s6 = self.sigma[:, 0], self.sigma[:, -1]
            cond = np.where(jac < s6, jac * (s1 + s6) / (s6 * (s6 - jac)), np.inf)
            exact = half * self.cond_terms[:, 0] + 0.5 * half**2 * self.cond_terms[:, 1]
            cond = np.where(np.isnan(exact), cond, exact)  # near the limit: the measured slope and curvature
        m = MARGIN_SAFETY
        first = m * half[:, None, None] * self.sensitivity
        return (first[:, 0] + hinge[:, None] ** 2 / arm, first[:, 1] + axis**2,
                first[:, 2] + (axis + turn[:, None]) ** 2, m * cond)

    def _parts(self, robot: Robot, half):
        """Distance to each limit after the margins: d_z / 1 cm, universal and spherical (rad) [n, 6] and the
        relative condition number [n, 1] (negative: violated or not proven; NaN counts as violated)."""
        lim = robot.limits
        dz, mu, ms, mc = self.margins(robot, half)
        with np.errstate(invalid="ignore"):
            parts = [(self.d[..., 2] - dz) / 0.01, lim.universal_joint_max - self.universal - mu,
                     lim.spherical_joint_max - self.spherical - ms,
                     ((lim.condition_number_max - self.condition - mc) / lim.condition_number_max)[:, None]]
        return [np.where(np.isnan(p), -np.inf, p) for p in parts]

    def slack(self, robot: Robot, half) -> np.ndarray:
        """Smallest distance to a limit after the margins [n] (negative: violated or not proven)."""
        return np.min([p.min(axis=1) for p in self._parts(robot, half)], axis=0)

    def raise_violation(self, robot: Robot, i: int, half, time: float, what: str) -> None:
        """Raise the typed error of sample ``i``'s tightest limit (its slack with the margins of ``half`` [n] is
        negative)."""
        lim = robot.limits
        parts = [p[i] for p in self._parts(robot, half)]
        which = int(np.argmin([p.min() for p in parts]))
        leg = int(np.argmin(parts[which]))
        _, mu, ms, _ = (x[i] for x in self.margins(robot, half))
        where = f"at t = {time:.4f} s"
        tolerance = (f" (+{np.degrees(max(mu[leg], ms[leg])):.3f} deg for the sampling and the vibration units' "
                     "reach)") if half[i] > 0 else ""
        if which == 0:
            raise UnreachablePoseError(
                f"workspace limit {where}: {what} takes the platform hinge of leg {leg + 1} to the base hinge plane "
                f"(d_z = {self.d[i, leg, 2]:.6g} m)", leg=leg + 1, limit_name="hinge_above_base",
                value=float(self.d[i, leg, 2]), limit=0.0, time=time)
        if which in (1, 2):
            angles, limit, name, label = ((self.universal[i], lim.universal_joint_max, "universal_joint_max",
                                           "universal (base)") if which == 1 else
                                          (self.spherical[i], lim.spherical_joint_max, "spherical_joint_max",
                                           "spherical (platform)"))
            raise JointLimitError(
                f"joint limit {where}: {what} takes the {label} joint of leg {leg + 1} to "
                f"{np.degrees(angles[leg]):.3f} deg{tolerance}, limit {np.degrees(limit):.3f} deg ({name})",
                leg=leg + 1, limit_name=name, value=float(angles[leg]), limit=limit, time=time)
        raise SingularPoseError(
            f"near-singular pose {where}: {what} reaches condition number {self.condition[i]:.4g}, "
            f"limit {lim.condition_number_max:.4g} (condition_number_max)", limit_name="condition_number_max",
            value=float(self.condition[i]), limit=lim.condition_number_max, time=time)


def _sensitivity(jac, r, axes, length, rot, universal, spherical) -> np.ndarray:
    """Sum over struts of |dq / dl_j| [n, 3, 6] for q = d_z (m/m), universal and spherical angle (rad/m) of each leg.

    With x = [dp; dphi] (dl = J x, J rows [n_i, r_i x n_i]) and dd_i = dp + dphi x r_i: d d_z,i = [e_z, r_i x
    e_z] x; the leg axis moves by dn_i = (I - n_i n_i') dd_i / l_i, so d cos(universal_i) = [w_i, r_i x w_i] x /
    l_i with w_i = e_z - n_z,i n_i, and d cos(spherical_i) = [v_i, r_i x v_i] x / l_i + [0, z_p x n_i] x with
    z_p = R e_z, v_i = z_p - (n_i . z_p) n_i; dq / dl = (dq / dx) J^-1 (one batched solve)."""
    count = jac.shape[0]
    ez = np.array([0.0, 0.0, 1.0])
    zp = rot[:, :, 2][:, None, :]  # [n, 1, 3]
    w = ez - axes[..., 2:3] * axes
    v = zp - np.einsum("nij,nij->ni", axes, np.broadcast_to(zp, axes.shape))[..., None] * axes
    with np.errstate(divide="ignore", invalid="ignore"):
        rows = np.concatenate([
            np.concatenate([np.broadcast_to(ez, r.shape), cross(r, np.broadcast_to(ez, r.shape))], axis=-1),
            -np.concatenate([w, cross(r, w)], axis=-1) / (length * np.sin(universal))[..., None],
            -(np.concatenate([v, cross(r, v)], axis=-1) / length[..., None]
              + np.concatenate([np.zeros_like(v), cross(np.broadcast_to(zp, axes.shape), axes)], axis=-1))
            / np.sin(spherical)[..., None]], axis=1)  # [n, 18, 6]: d q / d x
    try:
        per_length = np.linalg.solve(np.transpose(jac, (0, 2, 1)), np.transpose(rows, (0, 2, 1)))  # [n, 6, 18]
    except np.linalg.LinAlgError:
        per_length = np.full((count, 6, 18), np.inf)
    total = np.abs(per_length).sum(axis=1).reshape(count, 3, 6)
    return np.where(np.isfinite(total), total, np.inf)


def _condition_terms(robot: Robot, poses, rot, jac, condition) -> np.ndarray:
    """[n, 2]: sum over struts j of |d cond / d l_j| and of |d2 cond / d l_j^2| by central differences (strut
    steps of COND_STEP_M, the pose moved by J^-1 e_j per metre), where cond > COND_EXACT_ABOVE x its limit;
    NaN elsewhere (the Weyl bound is tight enough there)."""
    out = np.full((len(poses), 2), np.nan)
    near = np.flatnonzero(condition > COND_EXACT_ABOVE * robot.limits.condition_number_max)
    if not near.size:
        return out
    try:
        moves = np.linalg.inv(jac[near]) * COND_STEP_M  # [k, 6 (x), 6 (strut j)]
    except np.linalg.LinAlgError:
        return out
    shifted = []
    for sign in (1.0, -1.0):
        dx = sign * np.transpose(moves, (0, 2, 1))  # [k, j, 6]
        position = poses[near, None, :3] + dx[..., :3]
        turned = so3_exp(dx[..., 3:]) @ rot[near, None]
        shifted.append(condition_number(robot, np.concatenate([position, rpy_from_rotation(turned)], axis=-1)))
    centre = condition[near, None]
    out[near, 0] = np.abs(shifted[0] - shifted[1]).sum(axis=1) / (2 * COND_STEP_M)
    out[near, 1] = np.abs(shifted[0] - 2 * centre + shifted[1]).sum(axis=1) / COND_STEP_M**2
    return np.where(np.isfinite(out) | np.isnan(out), out, np.inf)


def _check_jumps(state: _PoseState, travel, times, what: str) -> None:
    """Neighbouring poses must lie within what their strut change allows (first order, twice over): a larger
    jump means the FK switched branches near a singularity."""
    if len(travel) == 0:
        return
    step = np.diff(state.poses, axis=0)
    jump = np.sqrt((step[:, :3] ** 2).sum(axis=1) + (0.1 * step[:, 3:]) ** 2 @ np.ones(3))
    sigma = np.minimum(state.sigma[:-1, -1], state.sigma[1:, -1])
    allowed = 2.0 * np.sqrt(6.0) * travel / sigma * 3.0 + 1e-9
    bad = ~(jump <= allowed)
    if bad.any():
        k = int(np.argmax(bad))
        raise UnreachablePoseError(
            f"workspace limit at t = {times[k + 1]:.4f} s: the platform pose of {what} jumps there (near a "
            "singularity)",
            limit_name="forward_kinematics", value=float(jump[k]), limit=float(allowed[k]), time=float(times[k + 1]))


def _refine(robot, sample_lengths, path: _Samples, failing, what, reach: float) -> bool:
    """Split the intervals next to the ``failing`` samples (indices whose margin does not fit) by as much as
    their margin needs, up to MAX_REFINE, in time order within MAX_REFINE_SAMPLES new samples; the new samples
    are solved from the poses interpolated between their interval's ends. Updates ``path`` in place."""
    t, lens, poses, travel, state = path.t, path.lengths, path.poses, path.travel, path.state
    exact = state.slack(robot, np.full(len(t), reach))
    margin = exact - state.slack(robot, _half(travel) + reach)  # what the spacing costs at each sample
    near = np.unique(np.concatenate([failing - 1, failing]))
    near = near[(near >= 0) & (near < len(t) - 1)]
    room = np.minimum(exact[near], exact[near + 1])
    need = np.maximum(margin[near], margin[near + 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(room > 0, np.ceil(1.25 * need / room) + 1, np.inf)
    # where even MAX_REFINE pieces cannot make the margin fit, the sample stays refused (it is within 1 / MAX_REFINE
    # of the spacing's margin of the limit): only the others are worth the samples
    hopeful = np.nan_to_num(ratio, nan=np.inf) <= MAX_REFINE
    near, ratio = near[hopeful], ratio[hopeful]
    if not near.size:
        return False
    split = np.clip(ratio, 2, MAX_REFINE).astype(int)
    within = np.cumsum(split - 1) <= MAX_REFINE_SAMPLES
    within[0] = True
    pieces = np.ones(len(t) - 1, dtype=int)
    pieces[near[within]] = split[within]
    total = int(pieces.sum())
    _check_count(total + 1, f"{what} runs close to a workspace limit for too long to check ({total + 1} samples)",
                 float(t[0]))
    interval = np.repeat(np.arange(len(t) - 1), pieces)
    step = np.arange(total) - np.repeat(np.cumsum(pieces) - pieces, pieces)
    frac = step / pieces[interval]
    merged_t = np.concatenate([t[interval] + np.diff(t)[interval] * frac, t[-1:]])
    merged_l = np.concatenate([lens[interval], lens[-1:]])
    merged_p = np.concatenate([poses[interval], poses[-1:]])
    added = np.flatnonzero(np.concatenate([step > 0, [False]]))
    merged_l[added] = np.asarray(sample_lengths(merged_t[added]), dtype=float)
    k, f = interval[added], frac[added][:, None]
    fk = _solve(robot, merged_l[added], poses[k] + (poses[k + 1] - poses[k]) * f)
    failed = ~(fk.converged & fk.assembly_ok & (fk.residual <= FK_RESIDUAL_M))
    if failed.any():
        first = int(np.argmax(failed))
        raise cast(UnreachablePoseError, _fk_failure(fk_row(fk, first), float(merged_t[added][first]), what))
    merged_p[added] = fk.pose
    # the travel of a piece: its chord bound; an interval left whole keeps its sub-grid bound
    merged_travel = _travel_bounds(merged_t, merged_l, robot.limits.strut_acceleration_max)
    whole = pieces[interval] == 1
    merged_travel[whole] = travel[interval[whole]]
    merged_state = _PoseState.at(robot, merged_p)
    _check_jumps(merged_state, merged_travel, merged_t, what)
    path.t, path.lengths, path.poses = merged_t, merged_l, merged_p
    path.travel, path.state = merged_travel, merged_state
    return True
