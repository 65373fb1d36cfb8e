"""The limit check read slab after slab (analysis.limit_scan) against the whole run's check at once
(analysis.limit_check.check_limits, the reference): every figure of a legal run and of each kind of violation
is the same, field for field, whatever the slabs, also with a seam inside the violation or a few states before
it; a state's differences across the seam are counted once."""

from __future__ import annotations

import numpy as np
import pytest
from test_limit_check import legal_run, spoil

from stewart_vibration.analysis.limit_check import check_limits, state_figures
from stewart_vibration.analysis.limit_scan import CARRY, LimitScan

KINDS = ["stroke", "strut velocity", "strut acceleration", "vibration unit displacement",
         "vibration unit acceleration", "universal joint angle", "condition number", "non-finite values",
         "time going back"]


def scanned(robot, joints, pose, clock, cuts, pose_cuts=None):
    """The scan's figures with the states cut at ``cuts`` and the poses at ``pose_cuts`` (default the same)."""
    scan = LimitScan(robot)
    t, cols = joints
    bounds = [0, *cuts, t.size]
    pt, poses = pose
    pose_bounds = [0, *(cuts if pose_cuts is None else pose_cuts), pt.size]
    for k in range(max(len(bounds), len(pose_bounds)) - 1):
        if k + 1 < len(bounds):
            a, b = bounds[k], bounds[k + 1]
            scan.add_states(t[a:b], {name: values[a:b] for name, values in cols.items()})
        if k + 1 < len(pose_bounds):
            a, b = pose_bounds[k], pose_bounds[k + 1]
            scan.add_poses(pt[a:b], poses[a:b])
    return scan.figures(clock)


def as_rows(figures):
    """The figures' fields, NaN written as "nan" (a NaN is equal to no number, and a NaN worst is a finding)."""
    def same(x):
        return "nan" if isinstance(x, float) and np.isnan(x) else x
    return [tuple(same(x) for x in (f.name, f.worst, f.time_s, f.leg, f.violations, f.least)) for f in figures]


@pytest.mark.parametrize("kind", KINDS)
def test_each_violation_scanned_in_slabs_gives_the_whole_runs_figures(robot, kind):
    joints, pose, clock, _name, _value = spoil(robot, kind)
    whole = as_rows(check_limits(robot, joints, pose, clock))
    n = joints[0].size
    # seams: at the violation (index 500), just before and after it within the stencils, and far from it
    for cuts in ([500], [495, 503], [498, 499, 501, 502], [250, 1000, 1500], [7, 13, 1999]):
        assert as_rows(scanned(robot, joints, pose, clock, [c for c in cuts if 0 < c < n])) == whole, cuts


def test_a_legal_run_in_many_small_slabs_is_the_whole_run(robot):
    joints, pose, clock = legal_run(robot)
    rng = np.random.default_rng(3)
    cuts = sorted(set(rng.integers(30, joints[0].size - 1, 40).tolist()))
    assert as_rows(scanned(robot, joints, pose, clock, cuts, pose_cuts=cuts[::3])) == \
        as_rows(check_limits(robot, joints, pose, clock))


def test_a_velocity_across_a_seam_counts_once(robot):
    joints, pose, clock = legal_run(robot)
    t, cols = joints
    pos = cols["position"].copy()
    pos[600:, 0] += 0.001  # leg 1 jumps 1 mm between states 599 and 600: one velocity sample beyond the limit
    joints = (t, dict(cols, position=pos))
    whole = {f.name: f for f in check_limits(robot, joints, pose, clock)}
    assert whole["strut velocity"].violations == 1
    for cut in (599, 600, 601, 600 - CARRY, 600 + CARRY):
        scan = {f.name: f for f in scanned(robot, joints, pose, clock, [cut])}
        velocity = scan["strut velocity"]
        assert velocity.violations == 1 and velocity.time_s == whole["strut velocity"].time_s


def test_one_state_has_no_rates():
    """A run of a single state has no velocity or acceleration (it was once judged by its lengths)."""
    from stewart_vibration import load_robot

    robot = load_robot()
    lengths = np.array([[0.17] * 6 + [0.0] * 6])
    figures = {f.name: f for f in state_figures(robot, np.array([1.0]), lengths)}
    assert figures["strut velocity"].worst == 0.0 and figures["strut acceleration"].worst == 0.0
    assert not figures["strut velocity"].violated


def test_a_stamp_going_back_at_the_seam_counts_once(robot):
    joints, pose, clock = legal_run(robot)
    t = joints[0].copy()
    t[600] = t[599] - 1e-4  # the first state of the second slab is stamped before the last of the first
    joints = (t, joints[1])
    whole = {f.name: f for f in check_limits(robot, joints, pose, clock)}
    assert whole["time going back (/clock, state stamps)"].violations == 1
    scan = {f.name: f for f in scanned(robot, joints, pose, clock, [600])}
    assert as_rows(scan.values()) == as_rows(whole.values())
