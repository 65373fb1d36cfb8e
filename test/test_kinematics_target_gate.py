"""The kinematics node's policy against trains of targets (motion.target_gate), without DDS: the node's own
sequence -- ask the gate, and on a take start the move as the node does (``begin_move`` at now + RECEIPT_DELAY_S) --
driven by targets arriving every 5 ms while the emulator's clock advances with them."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.kinematics import inverse_kinematics
from stewart_vibration.motion.force_guard import ForceGuard
from stewart_vibration.motion.profiles import minimum_jerk_duration
from stewart_vibration.motion.stop_planning import RECEIPT_DELAY_S
from stewart_vibration.motion.target_gate import TargetGate


def send(robot, guard, gate, goal_pose, sim_now, wall_now) -> str | None:
    """One target as the kinematics node takes it: the gate's refusal, or None after starting the move."""
    refusal = gate.refusal(sim_now, wall_now)
    if refusal is None:
        start = inverse_kinematics(robot, robot.home_pose)
        goal = inverse_kinematics(robot, goal_pose)
        duration = minimum_jerk_duration(start, goal, 0.01, 0.5)
        guard.begin_move(sim_now + RECEIPT_DELAY_S, duration, start, goal, robot.home_pose, goal_pose)
    return refusal


def train(robot, goals, period_s=0.005, rate_hz=5.0):
    """Targets ``goals`` sent every ``period_s`` (sim and wall clocks advance together): the refusals."""
    guard = ForceGuard(robot, 200.0, 15.0)
    gate = TargetGate(guard, rate_hz)
    return [send(robot, guard, gate, goal, 10.0 + i * period_s, 100.0 + i * period_s) for i, goal in enumerate(goals)]


def test_forty_targets_in_200_ms_start_one_move(robot):
    """The defect: each target arrived before the last move's estimated start, when the move was still "at rest",
    so all 40 were taken. Now a pending or running move refuses the next target until it has ended."""
    rng = np.random.default_rng(3)
    goals = [robot.home_pose + np.r_[rng.uniform(-0.005, 0.005, 3), 0, 0, 0] for _ in range(40)]
    refusals = train(robot, goals)
    assert refusals[0] is None
    assert all(r is not None and "a move is under way" in r for r in refusals[1:])


def test_moves_of_nothing_are_limited_by_the_rate(robot):
    """Targets where the platform already is never block (they move nothing), so the rate limit bounds them:
    rate_hz in a burst, then one per 1 / rate_hz."""
    refusals = train(robot, [robot.home_pose] * 40, rate_hz=5.0)  # 0.2 s: a burst of 5, one more token at 0.2 s
    taken = [i for i, r in enumerate(refusals) if r is None]
    assert taken == [0, 1, 2, 3, 4]
    assert all("target_rate_hz" in r for r in refusals if r is not None)


def test_the_next_target_is_taken_once_the_move_has_ended(robot):
    guard = ForceGuard(robot, 200.0, 15.0)
    gate = TargetGate(guard, 5.0)
    goal = robot.home_pose + [0, 0, 0.005, 0, 0, 0]
    assert send(robot, guard, gate, goal, 10.0, 100.0) is None
    end = guard.move.end
    assert "under way until" in send(robot, guard, gate, robot.home_pose, 10.01, 100.01)  # pending
    assert "under way until" in send(robot, guard, gate, robot.home_pose, end - 0.3, 100.5)  # running
    assert send(robot, guard, gate, robot.home_pose, end, 101.0) is None  # ended: taken


@pytest.mark.parametrize("rate_hz", [0.1, 1.0, 20.0])
def test_the_rate_limit_holds_over_a_long_train_of_moves_of_nothing(robot, rate_hz):
    refusals = train(robot, [robot.home_pose] * 2000, period_s=0.005, rate_hz=rate_hz)  # 10 s
    taken = sum(r is None for r in refusals)
    assert taken <= max(rate_hz, 1.0) + rate_hz * 10.0 + 1
