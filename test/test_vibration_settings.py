"""The planner's start check in the core (vibration/settings.py): what the planner node and the planning UI
both run before a start, without ROS."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.errors import InvalidInputError, StewartError, VibrationLimitError
from stewart_vibration.paper import paper_pose
from stewart_vibration.vibration.feasibility import check_command_limits
from stewart_vibration.vibration.settings import (
    SETTINGS,
    default_settings,
    duration_reason,
    parameters,
    settings_reason,
    start_check,
    start_refusal,
)


def test_defaults_cover_every_setting_within_their_declared_ranges(robot):
    s = default_settings(robot)
    assert tuple(s) == SETTINGS and settings_reason(robot, s) is None
    for name, spec in parameters(robot).items():
        assert spec.low <= s[name] <= spec.high, name


def test_one_duration_rule():
    assert duration_reason(0.0, 0.2) is None  # until stop
    assert duration_reason(0.4, 0.2) is None  # ramp-in + ramp-out, no steady part
    assert "2 ramp_s" in duration_reason(0.39, 0.2)


def test_start_check_of_the_paper_vibration_gives_the_first_window_from_rest(robot):
    s = dict(default_settings(robot), duration_s=3.0)
    started = start_check(robot, paper_pose(robot), s)
    first = started.first
    assert first.times[0] == 0.0 and np.allclose(first.position[0], 0.0) and np.allclose(first.velocity[0], 0.0)
    check_command_limits(robot.vibration_unit, first.times, first.position, first.velocity, first.acceleration)
    np.testing.assert_allclose(started.plan.frequency, 35.0)
    assert started.stream.finished  # 3 s fits max_lookahead_s (5 s): sent whole


@pytest.mark.parametrize("change, error, words", [
    ({"acceleration_g": 3.0}, VibrationLimitError, "longer ramp_s lowers the peak acceleration"),
    ({"duration_s": 0.3}, InvalidInputError, "2 ramp_s"),
    ({"frame": "world"}, InvalidInputError, "frame must be one of"),
])
def test_start_check_refuses_with_the_planners_reason(robot, change, error, words):
    s = dict(default_settings(robot), **change)
    with pytest.raises(error) as caught:
        start_check(robot, paper_pose(robot), s)
    assert isinstance(caught.value, StewartError)
    text = start_refusal(caught.value, s)
    assert text.startswith(f"infeasible vibration ({error.__name__})") and words in text
