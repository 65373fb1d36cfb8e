"""A move to a target pose planned without ROS (motion.move_plan): the leg trajectory against the minimum-jerk
closed form and an FK round trip, long moves thinned to the robot's bound, the speed the force guard allows,
the strut forces under tissue, and when a target is taken (each refusal's code, in order)."""

from __future__ import annotations

import numpy as np
import pytest
from tripped_guard import tripped_guard

from stewart_vibration import forward_kinematics, inverse_kinematics
from stewart_vibration.dynamics.tissue_config import load_tissue
from stewart_vibration.errors import GuardBlockedError, RefusedError, StrokeLimitError, TissueLimitError
from stewart_vibration.motion.force_guard import ForceGuard
from stewart_vibration.motion.move_plan import MovePlanner, MoveSpeed
from stewart_vibration.motion.paths import predicted_leg_forces
from stewart_vibration.motion.profiles import minimum_jerk
from stewart_vibration.motion.target_gate import TargetGate

MIN_DURATION_S, PERIOD_S = 0.5, 0.02


def planner(robot, rate_hz: float = 100.0, max_points: int = 5000, tissue=None, guard=None) -> MovePlanner:
    guard = guard if guard is not None else ForceGuard(robot, 200.0, 15.0)
    return MovePlanner(robot, guard, TargetGate(guard, rate_hz), max_points, tissue)


def test_the_trajectory_is_the_minimum_jerk_closed_form_and_ends_at_the_targets_lengths(robot):
    target = robot.home_pose + np.array([0.004, -0.002, 0.006, 0.02, -0.01, 0.03])
    l0, l1 = inverse_kinematics(robot, robot.home_pose), inverse_kinematics(robot, target)
    speed = 0.5 * robot.limits.strut_velocity_max
    plan = planner(robot).trajectory(l0, robot.home_pose, l1, target, speed, MIN_DURATION_S, PERIOD_S)
    duration = max(MIN_DURATION_S, 1.875 * np.abs(l1 - l0).max() / speed)  # peak speed 1.875 |dl| / T at T/2
    count = int(np.ceil(duration / PERIOD_S))
    assert plan.duration == pytest.approx(duration, rel=1e-12) and len(plan.times) == count
    np.testing.assert_allclose(plan.times, duration * np.arange(1, count + 1) / count, rtol=1e-12)
    s = plan.times[:, None] / duration
    np.testing.assert_allclose(plan.positions, l0 + (l1 - l0) * (10 * s**3 - 15 * s**4 + 6 * s**5), atol=1e-15)
    np.testing.assert_allclose(plan.velocities, (l1 - l0) * 30 * s**2 * (1 - s) ** 2 / duration, atol=1e-15)
    np.testing.assert_allclose(plan.accelerations, (l1 - l0) * 60 * s * (1 - s) * (1 - 2 * s) / duration**2,
                               atol=1e-12)
    assert np.abs(plan.velocities).max() <= speed * (1 + 1e-12)
    np.testing.assert_allclose(plan.positions[-1], l1, atol=1e-15)
    np.testing.assert_allclose(plan.velocities[-1], 0.0, atol=1e-15)
    fk = forward_kinematics(robot, plan.positions[-1], guess=target)
    np.testing.assert_allclose(fk.pose, target, atol=1e-10)  # the last point is the target, through FK


def test_short_moves_last_the_minimum_and_long_ones_are_thinned_to_the_robots_bound(robot):
    l0 = inverse_kinematics(robot, robot.home_pose)
    tiny = robot.home_pose + [1e-6, 0, 0, 0, 0, 0]
    short = planner(robot).trajectory(l0, robot.home_pose, inverse_kinematics(robot, tiny), tiny, 0.01,
                                      MIN_DURATION_S, 1.0)
    np.testing.assert_allclose(short.times, [0.25, 0.5], rtol=1e-12)  # at least two points
    far = robot.home_pose + [0, 0, 0.015, 0, 0, 0]
    l1 = inverse_kinematics(robot, far)
    thinned = planner(robot, max_points=7).trajectory(l0, robot.home_pose, l1, far, 0.01, MIN_DURATION_S, PERIOD_S)
    duration = 1.875 * np.abs(l1 - l0).max() / 0.01
    assert duration / PERIOD_S > 7
    np.testing.assert_allclose(thinned.times, duration * np.arange(1, 8) / 7, rtol=1e-12)


def test_a_move_runs_slower_while_the_estimates_lag(robot):
    guard = ForceGuard(robot, 200.0, 15.0, blind_travel=1.5e-3)
    moves = planner(robot, guard=guard)
    assert moves.speed(1.0) == MoveSpeed(robot.limits.strut_velocity_max, float("inf"))  # no estimator heard yet
    guard.estimates.arrived([1.0])
    guard.estimates.checked(1.1)  # the newest estimate 0.1 s behind the newest state
    fast, slow = moves.speed(1.0), moves.speed(0.5)
    assert fast.slowed and fast.value == pytest.approx(1.5e-3 / 0.1) and fast.asked == robot.limits.strut_velocity_max
    assert not slow.slowed and slow.value == pytest.approx(0.5 * robot.limits.strut_velocity_max)
    guard.set_limits(0.0, 0.0)  # the guard off: never slowed
    assert not moves.speed(1.0).slowed


def test_a_target_is_refused_in_order_reachable_ready_not_blocked_not_too_soon(robot):
    home, l0 = robot.home_pose, inverse_kinematics(robot, robot.home_pose)
    target = home + [0, 0, 0.003, 0, 0, 0]
    moves = planner(robot, rate_hz=1.0)
    with pytest.raises(StrokeLimitError):  # unreachable before anything else, even with nothing measured
        moves.admit(home + [0, 0, 0.2, 0, 0, 0], None, None, 0.0, 0.0)
    with pytest.raises(RefusedError) as not_ready:
        moves.admit(target, None, None, 0.0, 0.0)
    assert not_ready.value.outcome == "NOT_READY"
    np.testing.assert_allclose(moves.admit(target, l0, home, 0.0, 10.0), inverse_kinematics(robot, target))
    with pytest.raises(RefusedError, match="target_rate_hz 1") as busy:  # a second target within a second
        moves.admit(target, l0, home, 0.0, 10.5)
    assert busy.value.outcome == "BUSY"
    moves.admit(target, l0, home, 0.0, 11.0)
    moves.guard.begin_move(0.0, 2.0, l0, inverse_kinematics(robot, target), home, target)
    with pytest.raises(RefusedError, match="under way until") as under_way:
        moves.admit(target, l0, home, 1.0, 20.0)
    assert under_way.value.outcome == "BUSY"

    blocked = planner(robot, guard=tripped_guard(robot))
    held = home + [0, 0, 0.002, 0, 0, 0]
    with pytest.raises(GuardBlockedError):
        blocked.admit(held + [0, 0, 0.001, 0, 0, 0], l0, held, 5.0, 0.0)
    blocked.admit(home, l0, held, 5.0, 0.0)  # back, away from the load: taken


def test_under_tissue_the_first_overloaded_sample_is_refused_with_its_waypoint(robot):
    tissue = load_tissue("tissue.yaml", robot)
    moves = planner(robot, tissue=tissue)
    l0 = inverse_kinematics(robot, robot.home_pose)
    near = robot.home_pose + [0, 0, 0.008, 0, 0, 0]
    moves.trajectory(l0, robot.home_pose, inverse_kinematics(robot, near), near, 0.01, MIN_DURATION_S, PERIOD_S)
    far = robot.home_pose + [0, 0, 0.020, 0, 0, 0]
    l1 = inverse_kinematics(robot, far)
    with pytest.raises(TissueLimitError, match="strut_force_max_n") as refused:
        moves.trajectory(l0, robot.home_pose, l1, far, 0.01, MIN_DURATION_S, PERIOD_S)
    # independently: the samples' poses and the forces they need; waypoint k is sample k (0: the start)
    duration = 1.875 * np.abs(l1 - l0).max() / 0.01
    count = int(np.ceil(duration / PERIOD_S))
    times = duration * np.arange(1, count + 1) / count
    poses = forward_kinematics(robot, minimum_jerk(l0, l1, duration, times)[0],
                               guess=np.broadcast_to(robot.home_pose, (count, 6))).pose
    over = (np.abs(predicted_leg_forces(robot, poses, tissue)) > robot.limits.strut_force_max).any(axis=1)
    assert refused.value.waypoint == int(np.argmax(over)) + 1 and 1 < refused.value.waypoint <= count
