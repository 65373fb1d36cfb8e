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
at the sample (``pose_margins``: dq / dx from the leg geometry times J^-1, one batched solve; for the condition
number Weyl's bound on the singular values, or central differences near its limit), the allowance is the
square of a Lipschitz bound from the Jacobian's smallest singular value (``PoseState.margins``; measured
against FK in the tests). The vibration units ride on the struts: the real hinge-to-hinge lengths stray up to
their amplitude_max (the ``reach``) from the path, so each sample must keep q plus its margin for h = D / 2 +
reach within the limit (the reach alone costs 0.1-0.3 deg of joint angle near the joint limits). Where the
spacing's share of that margin does not fit, the neighbouring intervals are resampled finer, as much finer as
it needs (up to MAX_REFINE times per round, REFINE_ROUNDS rounds), so a path is refused only where the reach
crosses the limit or within a few 1e-6 deg of that (the message names the margin).

The parts: ``path_sampling`` (the sub-grid and its travel bounds), ``path_fk`` (the poses along the path),
``pose_margins`` (the limits at a sample and their margins), ``path_refinement`` (the finer resampling).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np

from ..errors import UnreachablePoseError
from ..robot import Robot
from .limits import check_stroke
from .path_fk import check_jumps, poses_along
from .path_refinement import PathSamples, refine
from .path_sampling import PATH_SPACING_M, check_sample_count, half_travel, subgrid
from .pose_margins import PoseState

REFINE_ROUNDS = 6  # rounds of subdivision near a limit


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
    times, lengths, bound = subgrid(robot, sample_lengths, float(start), float(end), knots, what)
    check_stroke(lengths, lengths, lim, what=f"length along {what}")
    cumulative = np.concatenate([[0.0], np.cumsum(bound)])
    picks = np.flatnonzero(np.diff(np.floor(cumulative / (0.5 * PATH_SPACING_M)), prepend=-1.0) > 0)
    picks = np.union1d(picks, [0, times.size - 1])
    check_sample_count(picks.size, f"{what} needs {picks.size} workspace samples (its struts may travel "
                 f"{cumulative[-1]:.3f} m)", float(start))
    t, lens, travel = times[picks], lengths[picks], np.diff(cumulative[picks])
    poses, failure = poses_along(robot, t, lens, cumulative[picks], start_pose, what)
    if not len(poses):
        raise cast(UnreachablePoseError, failure)
    path = PathSamples(t[:len(poses)], lens[:len(poses)], poses, travel[:len(poses) - 1], PoseState.at(robot, poses))
    try:
        check_jumps(path.state, path.travel, path.t, what)
    except UnreachablePoseError as jump:
        failure = failure if failure is not None and failure.time < jump.time else jump
        path.cut(robot, int(np.searchsorted(path.t, jump.time)))
    for _ in range(REFINE_ROUNDS):
        hard = np.flatnonzero(path.state.slack(robot, np.full(len(path.t), reach)) < 0)
        if hard.size:  # a sample beyond a limit: only what comes before it can hold an earlier violation
            path.cut(robot, int(hard[0]) + 1)
            failure = None
        failing = np.flatnonzero(path.state.slack(robot, half_travel(path.travel) + reach) < 0)
        if not failing.size or (hard.size and failing[0] == len(path.t) - 1):
            break  # nothing left to prove, or the first failure is a sample beyond the limit
        # where the margin does not fit: resample the neighbouring intervals finer
        if not refine(robot, sample_lengths, path, failing[:np.searchsorted(failing, len(path.t) - 1)] if hard.size
                       else failing, what, reach):
            break
    slack = path.state.slack(robot, half_travel(path.travel) + reach)
    if (slack < 0).any():
        first = int(np.argmax(slack < 0))
        path.state.raise_violation(robot, first, half_travel(path.travel) + reach, float(path.t[first]), what)
    if failure is not None:
        raise failure
    return PathPoses(path.t, path.lengths, path.poses, path.state.condition)
