"""A reduction move as an action goal (motion.move_goal) and the force guard's side of it (ForceGuard.cancel,
a goal's own limits): pure, no ROS."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration import inverse_kinematics
from stewart_vibration.errors import InvalidInputError
from stewart_vibration.motion.force_guard import ForceGuard
from stewart_vibration.motion.move_goal import SETTLE_S, MoveWatch, move_request, pose_errors
from stewart_vibration.motion.profiles import minimum_jerk


def watch(robot, **overrides):
    values = {"position_tolerance": 1e-4, "angle_tolerance": 1e-3, "goal_time": 2.0, "pause_timeout": 30.0}
    values.update(overrides)
    return MoveWatch(robot.home_pose, robot.home_pose + np.r_[0.0, 0.0, 0.01, 0.0, 0.0, 0.0], **values)


def test_a_goals_values_are_checked_and_zero_means_the_nodes():
    request = move_request(np.zeros(6), 0.0, 0.0, 0.0, 0.5, 200.0, 15.0)
    assert (request.speed_scale, request.force_limit, request.moment_limit) == (0.5, 200.0, 15.0)
    lower = move_request(np.zeros(6), 0.9, 50.0, 2.0, 0.5, 200.0, 15.0)
    assert (lower.speed_scale, lower.force_limit, lower.moment_limit) == (0.9, 50.0, 2.0)
    assert move_request(np.zeros(6), 0.0, 80.0, 0.0, 0.5, 0.0, 0.0).force_limit == 80.0  # the node's guard is off
    for args, words in (((1.5, 0, 0), "speed_scale 1.5"), ((-0.1, 0, 0), "speed_scale"),
                        ((1e-300, 0, 0), "outside"), ((5e-324, 0, 0), "outside"),
                        ((float("nan"), 0, 0), "not finite"), ((0, 300.0, 0), "only lower"),
                        ((0, 0, 16.0), "guard_moment_nm 15"), ((0, -1.0, 0), "negative"),
                        ((0, float("inf"), 0), "not finite")):
        with pytest.raises(InvalidInputError, match=words):
            move_request(np.zeros(6), *args, 0.5, 200.0, 15.0)


def test_pose_errors_are_the_distance_and_the_rotation_angle():
    a = np.zeros(6)
    b = np.r_[0.003, -0.004, 0.0, 0.0, 0.0, 0.02]
    position, angle = pose_errors(a, b)
    assert position == pytest.approx(0.005) and angle == pytest.approx(0.02)


def test_a_move_succeeds_within_tolerance_after_its_end_or_times_out(robot):
    w = watch(robot)
    w.moving(5.0)
    target = w.target
    assert w.update(5.0 + SETTLE_S - 1e-3, target) is None  # not before the planned end and the settle
    assert w.update(5.0 + SETTLE_S, target + np.r_[2e-4, 0, 0, 0, 0, 0]) is None  # outside the tolerance: waits
    end = w.update(5.0 + SETTLE_S + 0.1, target + np.r_[5e-5, 0, 0, 0, 0, 0])
    assert end.outcome == "SUCCEEDED" and "50.0 um" in end.message
    late = watch(robot)
    late.moving(5.0)
    assert late.update(6.0, late.target + np.r_[0, 0, 1e-3, 0, 0, 0]) is None
    assert late.update(7.0, late.target + np.r_[0, 0, 1e-3, 0, 0, 0]).outcome == "TIMEOUT"


def test_stops_end_the_goal_with_their_reason_once_over_and_a_guard_stop_outranks_a_cancel(robot):
    w = watch(robot)
    w.moving(5.0)
    w.stopping("GUARD_STOPPED", 3.0, 2.5, "force guard tripped")
    w.stopping("CANCELED", 3.5, 2.6, "cancelled")  # the client cancels while the guard stops: still the guard's
    assert w.update(3.0, w.start_pose) is None
    end = w.update(3.0 + SETTLE_S, w.start_pose)
    assert end.outcome == "GUARD_STOPPED" and end.message.startswith("force guard tripped; at rest")
    assert w.update(10.0, w.target) is end  # the first end stays


def test_a_pause_waits_for_the_resumed_move_or_times_out(robot):
    w = watch(robot, pause_timeout=5.0)
    w.moving(5.0)
    w.stopping("PAUSED", 2.0, 1.5)
    assert w.update(4.0, w.start_pose) is None  # a pause never ends the goal by itself at its stop's end
    w.moving(9.0)  # resumed
    assert w.update(9.0 + SETTLE_S, w.target).outcome == "SUCCEEDED"
    stuck = watch(robot, pause_timeout=5.0)
    stuck.stopping("PAUSED", 2.0, 1.5)
    assert stuck.update(6.4, stuck.start_pose) is None
    assert stuck.update(6.6, stuck.start_pose).outcome == "TIMEOUT"


def test_the_robots_end_is_final_and_progress_runs_from_start_to_target(robot):
    w = watch(robot)
    assert w.progress(w.start_pose) == 0.0 and w.progress(w.target) == 1.0
    assert w.progress((w.start_pose + w.target) / 2) == pytest.approx(0.5)
    w.end("EMERGENCY_STOPPED", "the robot stopped the move itself (emergency stop)")
    w.end("ROBOT_REFUSED", "later")
    assert w.update(0.0, w.start_pose).outcome == "EMERGENCY_STOPPED"


def running_guard(robot, force_limit=None):
    """A guard watching a 1 s move of +10 mm in z from home, its states fed up to 0.4 s."""
    guard = ForceGuard(robot, 200.0, 15.0)
    start = robot.home_pose
    goal = start + np.r_[0.0, 0.0, 0.01, 0.0, 0.0, 0.0]
    l0, l1 = inverse_kinematics(robot, start), inverse_kinematics(robot, goal)
    guard.begin_move(0.0, 1.0, l0, l1, start, goal, force_limit, None)
    times = np.arange(0.0, 0.4, 0.002)
    guard.observe_states(times, minimum_jerk(l0, l1, 1.0, times)[0])
    return guard, l0, l1


def test_a_cancel_stops_the_move_along_its_path_within_the_acceleration_limit_and_latches_nothing(robot):
    guard, l0, l1 = running_guard(robot)
    stop = guard.cancel(0.4)
    assert stop is not None and 0.0 < stop.progress < 1.0
    assert np.allclose(stop.lengths, l0 + (l1 - l0) * stop.progress)  # on the move's line in leg space
    assert stop.peak_accel <= guard.deceleration_scale * robot.limits.strut_acceleration_max + 1e-9
    assert not guard.tripped and guard.move.stopped and guard.move.end == pytest.approx(stop.receipt_time +
                                                                                       stop.duration)
    assert guard.move_under_way(0.45) is None  # no longer a move to wait for: the goal's own BUSY holds
    assert guard.cancel(0.42) is None  # one cancel; a refused stop is planned again with a wider window
    again = guard.cancel(0.42, attempt=1)
    assert again is not None and again.duration >= stop.duration - 1e-9
    assert guard.assess(0.45) is None  # a stopping move is not judged against its original plan


def test_a_goals_own_force_limit_watches_its_move(robot):
    guard, _, _ = running_guard(robot, force_limit=20.0)
    assert guard.limits() == (20.0, 15.0)
    stamps = np.arange(0.25, 0.4, 0.002)
    forces = np.zeros((stamps.size, 6))
    forces[:, 2] = 100.0 * (stamps - 0.25)  # rising to 15 N: under the node's 200 N, over the goal's 20 N soon
    trip = guard.observe(stamps, forces, 0.4)
    assert trip is not None and trip.which == "force" and trip.limit == 20.0
    assert "the force limit 20 N" in guard.message()
    node_limits, _, _ = running_guard(robot)  # the same load under the node's 200 N: no trip
    assert node_limits.observe(stamps, forces, 0.4) is None
