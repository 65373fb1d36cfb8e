"""Bounded commands (emulation.command_size): a leg trajectory of more than MAX_TRAJECTORY_POINTS points and a
vibration window of more than the planner's own bound are refused from their size with the typed reason
before anything big is built; a message too long to carry a command within the bound is refused from its
byte length before it is decoded; every command within the bounds gets through the size checks."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.emulation.command_size import (
    LEG_TRAJECTORY,
    MAX_TRAJECTORY_POINTS,
    MAX_WINDOW_POINTS,
    VIBRATION_WINDOW,
    check_point_count,
    max_message_bytes,
    raw_command_refusal,
)
from stewart_vibration.emulation.safety_controller import SafetyController
from stewart_vibration.errors import ActuatorLimitError, VibrationLimitError
from stewart_vibration.messages.joint_trajectory import encode_joint_trajectory
from stewart_vibration.robot import LEG_NAMES, VIB_NAMES
from stewart_vibration.vibration.settings import MAX_WINDOW_SAMPLES


def slow_trajectory(home, count, duration=100.0):
    """``count`` points of a 1 mm minimum-jerk-like creep over ``duration`` s (legal per strut)."""
    t = np.linspace(duration / count, duration, count)
    s = t / duration
    ease = s**3 * (10 - 15 * s + 6 * s**2)
    pos = home + 1e-3 * ease[:, None]
    vel = 1e-3 * (30 * s**2 * (1 - s) ** 2 / duration)[:, None] * np.ones(6)
    return t, pos, vel


def test_the_bounds_are_the_ones_documented(robot):
    assert MAX_WINDOW_POINTS == MAX_WINDOW_SAMPLES  # every window the planner may send is taken
    for kind, limit, error in ((LEG_TRAJECTORY, MAX_TRAJECTORY_POINTS, ActuatorLimitError),
                               (VIBRATION_WINDOW, MAX_WINDOW_POINTS, VibrationLimitError)):
        check_point_count(limit, kind)
        with pytest.raises(error) as refused:
            check_point_count(limit + 1, kind)
        assert refused.value.limit_name == "max_points" and refused.value.value == limit + 1
        assert refused.value.limit == limit and str(limit) in str(refused.value)


def test_a_maximal_leg_trajectory_message_passes_the_byte_check_and_one_beyond_it_does_not(robot):
    home = SafetyController(robot, 5e-4).home_lengths
    t, pos, vel = slow_trajectory(home, MAX_TRAJECTORY_POINTS)
    maximal = encode_joint_trajectory(LEG_NAMES, 0.0, t, pos, vel, np.zeros_like(pos))
    assert len(maximal) <= max_message_bytes(LEG_TRAJECTORY) and raw_command_refusal(maximal, LEG_TRAJECTORY) is None
    t2, pos2, vel2 = slow_trajectory(home, 2 * MAX_TRAJECTORY_POINTS)
    oversized = encode_joint_trajectory(LEG_NAMES, 0.0, t2, pos2, vel2, np.zeros_like(pos2))
    reason = raw_command_refusal(oversized, LEG_TRAJECTORY)
    assert reason is not None and str(len(oversized)) in reason and str(MAX_TRAJECTORY_POINTS) in reason
    assert raw_command_refusal(oversized, VIBRATION_WINDOW) is None  # a window may be longer


def test_the_emulator_refuses_one_point_too_many_and_nothing_moves(robot):
    ctl = SafetyController(robot, 5e-4)
    home = ctl.home_lengths
    t, pos, vel = slow_trajectory(home, MAX_TRAJECTORY_POINTS + 1)
    before = ctl.struts.sample([0.0, 50.0])
    with pytest.raises(ActuatorLimitError) as refused:
        ctl.command_struts(0.0, LEG_NAMES, 0.0, t, pos, vel)
    assert refused.value.limit_name == "max_points"
    after = ctl.struts.sample([0.0, 50.0])
    assert all(np.array_equal(a, b) for a, b in zip(before, after, strict=True))
    # the same move in MAX_TRAJECTORY_POINTS points is taken
    t, pos, vel = slow_trajectory(home, MAX_TRAJECTORY_POINTS)
    running = ctl.command_struts(0.0, LEG_NAMES, 0.0, t, pos, vel)
    assert len(running.times) == MAX_TRAJECTORY_POINTS


def test_a_window_beyond_the_planners_bound_is_refused_and_recorded(robot):
    ctl = SafetyController(robot, 5e-4)
    count = MAX_WINDOW_POINTS + 1
    t = np.arange(count) * 1e-4
    with pytest.raises(VibrationLimitError) as refused:
        ctl.command_vibration(0.0, VIB_NAMES, 0.1, t, np.zeros((count, 6)), np.zeros((count, 6)))
    assert refused.value.limit_name == "max_points"
    assert ctl.status.report.refused == 1 and str(MAX_WINDOW_POINTS) in ctl.status.report.event_reason
    assert ctl.status.report.event_outcome == "LIMIT_EXCEEDED"
    assert ctl.vibration.times.size == 0
