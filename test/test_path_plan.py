"""A planned path through waypoints without ROS (motion.path_plan, what kinematics/plan_path answers): the
samples against the straight SE(3) segments, the duration against the minimum-jerk closed form per segment,
and a refused segment's code, waypoint (as the request counts them) and time along the path."""

from __future__ import annotations

import numpy as np
import pytest
from tripped_guard import tripped_guard

from stewart_vibration import inverse_kinematics
from stewart_vibration.dynamics.tissue_config import load_tissue
from stewart_vibration.errors import InvalidInputError, RefusedError, StrokeLimitError
from stewart_vibration.kinematics.rotations import rotation_from_rpy, so3_log
from stewart_vibration.motion.force_guard import ForceGuard
from stewart_vibration.motion.path_plan import SegmentRefused, path_waypoints, plan_path

MIN_DURATION_S = 0.5


def guard(robot) -> ForceGuard:
    return ForceGuard(robot, 200.0, 15.0)


def segment_duration(robot, a, b, speed_scale: float) -> float:
    """The closed form: a minimum-jerk move of the struts peaks at 1.875 |dl| / T."""
    dl = np.abs(inverse_kinematics(robot, b) - inverse_kinematics(robot, a)).max()
    return max(MIN_DURATION_S, 1.875 * dl / (speed_scale * robot.limits.strut_velocity_max))


def test_one_waypoint_starts_at_the_estimate_and_none_is_refused(robot):
    a, b = robot.home_pose, robot.home_pose + [0.001, 0, 0, 0, 0, 0]
    with pytest.raises(InvalidInputError, match="at least one waypoint"):
        path_waypoints([], a)
    with pytest.raises(RefusedError) as not_ready:
        path_waypoints([b], None)
    assert not_ready.value.outcome == "NOT_READY"
    estimate = a.copy()
    poses, offset = path_waypoints([b], estimate)
    assert offset == 1 and np.array_equal(poses[0], a) and poses[1] is b
    poses[0][0] = 1.0
    assert estimate[0] == a[0]  # the estimate is copied, never changed
    assert path_waypoints([a, b], None) == ([a, b], 0)


def test_the_samples_follow_each_segment_and_the_duration_sums_the_segments(robot):
    start = robot.home_pose
    mid = start + [0.0104, 0, 0, 0, 0, 0.1]  # no step count on an integer: 10.4 mm, 5.7 deg
    end = mid + [0, -0.0042, 0.0031, 0.02, 0, 0]  # 5.2 mm, 1.1 deg
    plan = plan_path(robot, [start, mid, end], 0, 0.5, 0.25, MIN_DURATION_S, guard(robot))
    first = int(np.ceil(max(0.0104 / 1e-3, 0.1 / np.radians(1.0)))) + 1  # 1 mm / 1 deg steps, both ends included
    second = int(np.ceil(max(np.hypot(0.0042, 0.0031) / 1e-3, 0.02 / np.radians(1.0)))) + 1
    assert (first, second) == (12, 7)
    assert len(plan.samples) == first + second - 1  # the shared waypoint once
    assert np.array_equal(plan.samples[0], start) and np.array_equal(plan.samples[first - 1], mid)
    assert np.array_equal(plan.samples[-1], end)
    steps = np.diff(plan.samples, axis=0)
    assert np.linalg.norm(steps[:, :3], axis=1).max() <= 1e-3 * (1 + 1e-9)
    angles = [np.linalg.norm(so3_log(rotation_from_rpy(q[3:]) @ rotation_from_rpy(p[3:]).T))
              for p, q in zip(plan.samples[:-1], plan.samples[1:], strict=True)]
    assert max(angles) <= np.radians(1.0) * (1 + 1e-9)
    expected = segment_duration(robot, start, mid, 0.5) + segment_duration(robot, mid, end, 0.5)
    assert plan.duration == pytest.approx(expected, rel=1e-12)
    # speed scale 0: the default; the duration scales with 1 / speed beyond the shortest move
    slower = plan_path(robot, [start, mid], 0, 0.0, 0.25, MIN_DURATION_S, guard(robot))
    assert slower.duration == pytest.approx(segment_duration(robot, start, mid, 0.25), rel=1e-12)
    with pytest.raises(InvalidInputError, match="speed_scale"):
        plan_path(robot, [start, mid], 0, 2.0, 0.25, MIN_DURATION_S, guard(robot))


def test_a_refused_segment_names_its_waypoint_and_the_time_the_path_reaches_it(robot):
    start, mid = robot.home_pose, robot.home_pose + [0.01, 0, 0, 0, 0, 0.1]
    beyond = start + [0, 0, 0.2, 0, 0, 0]
    with pytest.raises(SegmentRefused, match="stroke") as refused:
        plan_path(robot, [start, mid, beyond], 0, 0.5, 0.5, MIN_DURATION_S, guard(robot))
    assert refused.value.outcome == "UNREACHABLE_POSE" and isinstance(refused.value.__cause__, StrokeLimitError)
    assert refused.value.waypoint == 2
    assert refused.value.time_s == pytest.approx(segment_duration(robot, start, mid, 0.5), rel=1e-12)
    # one waypoint: the estimate is not the request's; its only waypoint is 0
    with pytest.raises(SegmentRefused) as alone:
        plan_path(robot, *path_waypoints([beyond], start), 0.5, 0.5, MIN_DURATION_S, guard(robot))
    assert (alone.value.waypoint, alone.value.time_s) == (0, 0.0)


def test_a_tripped_guard_and_the_tissue_refuse_their_segments(robot):
    tripped = tripped_guard(robot)
    side = robot.home_pose + [0.003, 0, 0, 0, 0, 0]
    with pytest.raises(SegmentRefused, match="reset_guard") as blocked:  # sideways, then up the stopped direction
        plan_path(robot, [robot.home_pose, side, side + [0, 0, 0.002, 0, 0, 0]], 0, 0.5, 0.5, MIN_DURATION_S,
                  tripped)
    assert (blocked.value.outcome, blocked.value.waypoint) == ("GUARD_BLOCKED", 2)
    tissue = load_tissue("tissue.yaml", robot)
    far = robot.home_pose + [0, 0, 0.020, 0, 0, 0]
    with pytest.raises(SegmentRefused, match="strut_force_max_n") as overloaded:
        plan_path(robot, [robot.home_pose, far], 0, 0.5, 0.5, MIN_DURATION_S, guard(robot), tissue)
    assert (overloaded.value.outcome, overloaded.value.waypoint, overloaded.value.time_s) == ("TISSUE_LIMIT", 1, 0.0)
    near = robot.home_pose + [0, 0, 0.008, 0, 0, 0]
    assert len(plan_path(robot, [robot.home_pose, near], 0, 0.5, 0.5, MIN_DURATION_S, guard(robot), tissue).samples)
