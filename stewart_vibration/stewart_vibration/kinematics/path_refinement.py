"""The finer resampling of a strut path near a workspace limit: the checked samples (times s, strut lengths m,
poses m / rad in the base frame) and the intervals next to a sample whose margin does not fit, split by as much
as the margin needs (up to MAX_REFINE pieces) and solved from the interpolated poses.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np

from ..errors import UnreachablePoseError
from ..robot import Robot
from .path_fk import FK_RESIDUAL_M, check_jumps, fk_failure, fk_row, warm_started_fk
from .path_sampling import check_sample_count, half_travel, travel_bounds
from .pose_margins import PoseState

MAX_REFINE = 64  # largest subdivision of an interval near a limit, per round
MAX_REFINE_SAMPLES = 1000  # new samples per round (the earliest intervals first)


@dataclass
class PathSamples:
    """The checked samples of a path: times [n] (s), lengths and poses [n, 6], the travel bound of each interval
    [n - 1] (m) and the pose quantities."""

    t: np.ndarray
    lengths: np.ndarray
    poses: np.ndarray
    travel: np.ndarray
    state: PoseState

    def cut(self, robot: Robot, keep: int) -> None:
        """Keep the first ``keep`` samples."""
        self.t, self.lengths, self.poses = self.t[:keep], self.lengths[:keep], self.poses[:keep]
        self.travel = self.travel[:max(keep - 1, 0)]
        self.state = PoseState.at(robot, self.poses)



def refine(robot, sample_lengths, path: PathSamples, failing, what, reach: float) -> bool:
    """Split the intervals next to the ``failing`` samples (indices whose margin does not fit) by as much as
    their margin needs, up to MAX_REFINE, in time order within MAX_REFINE_SAMPLES new samples; the new samples
    are solved from the poses interpolated between their interval's ends. Updates ``path`` in place."""
    t, lens, poses, travel, state = path.t, path.lengths, path.poses, path.travel, path.state
    exact = state.slack(robot, np.full(len(t), reach))
    margin = exact - state.slack(robot, half_travel(travel) + reach)  # what the spacing costs at each sample
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
    check_sample_count(total + 1, f"{what} runs close to a workspace limit for too long to check ({total + 1} samples)",
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
    fk = warm_started_fk(robot, merged_l[added], poses[k] + (poses[k + 1] - poses[k]) * f)
    failed = ~(fk.converged & fk.assembly_ok & (fk.residual <= FK_RESIDUAL_M))
    if failed.any():
        first = int(np.argmax(failed))
        raise cast(UnreachablePoseError, fk_failure(fk_row(fk, first), float(merged_t[added][first]), what))
    merged_p[added] = fk.pose
    # the travel of a piece: its chord bound; an interval left whole keeps its sub-grid bound
    merged_travel = travel_bounds(merged_t, merged_l, robot.limits.strut_acceleration_max)
    whole = pieces[interval] == 1
    merged_travel[whole] = travel[interval[whole]]
    merged_state = PoseState.at(robot, merged_p)
    check_jumps(merged_state, merged_travel, merged_t, what)
    path.t, path.lengths, path.poses = merged_t, merged_l, merged_p
    path.travel, path.state = merged_travel, merged_state
    return True
