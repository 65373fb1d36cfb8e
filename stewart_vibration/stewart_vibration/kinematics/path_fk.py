"""The platform poses along a strut path (m, rad, base frame) by forward kinematics warm-started along it
(sequential anchors, then one batched solve), the refusal of a sample without a converged pose, and the check
that neighbouring poses do not jump (the FK switched branches near a singularity).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..errors import ForwardKinematicsError, UnreachablePoseError
from ..robot import Robot
from .fk import ForwardKinematicsResult, forward_kinematics
from .geometry import joint_angles_from_axes, leg_vectors_from_rotation
from .rotations import rotation_from_rpy

if TYPE_CHECKING:
    from .pose_margins import PoseState

ANCHOR_TRAVEL_M = 5e-3  # strut travel between the sequential warm-start anchors of the FK (m)
FK_RESIDUAL_M = 1e-9  # the FK of every sample must reproduce its lengths this closely (m)
FK_ITERATIONS = 15  # Newton from a warm start this close converges in < 6 iterations where a pose exists
FK_TOLERANCE_M = 1e-11  # Newton stops here (1e-12, the default, costs extra iterations at round-off)


def poses_along(robot: Robot, times, lengths, travel, start_pose, what):
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
        fk = warm_started_fk(robot, lengths[index], guess)
        failure = fk_failure(fk, float(times[index]), what)
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
        fk = warm_started_fk(robot, lengths[rest], guesses)
        bad = ~(fk.converged & fk.assembly_ok & (fk.residual <= FK_RESIDUAL_M))
        poses[rest] = fk.pose
        if bad.any():
            first = int(np.argmax(bad))
            failure = fk_failure(fk_row(fk, first), float(times[rest][first]), what)
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


def warm_started_fk(robot: Robot, lengths, guess):
    """Warm-started FK of strut lengths [..., 6] (no stroke check: the sub-grid had it)."""
    return forward_kinematics(robot, lengths, guess=guess, check_limits=False, max_iter=FK_ITERATIONS,
                              tol=FK_TOLERANCE_M)


def fk_row(fk, index: int):
    """One row of a batched ForwardKinematicsResult, as a result of its own."""
    return ForwardKinematicsResult(*(np.asarray(getattr(fk, f))[index] for f in
                                     ("pose", "rotation", "iterations", "residual", "converged", "assembly_ok")))


def fk_failure(fk, time: float, what: str) -> UnreachablePoseError | None:
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



def check_jumps(state: PoseState, travel, times, what: str) -> None:
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

