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


@pytest.mark.parametrize("change, words", [
    ({"phase_rad": float("nan")}, "phase_rad must be finite"),
    ({"lead_s": -1e-9}, "lead_s must be >= 0"),
    ({"duration_s": -1e-9}, "duration_s must be >= 0"),
    ({"lead_s": 0.5, "start_lead_s": 0.5 - 1e-9}, "start_lead_s"),
    ({"ramp_s": 0.25, "duration_s": 0.5 - 1e-9}, "2 ramp_s"),
    ({"lookahead_s": 0.5, "window_period_s": 0.5}, "must exceed window_period_s"),
    ({"direction": [0.0, 0.0, 0.0]}, "not all zero"),
    ({"direction": [0.0, float("nan"), 1.0]}, "3 finite values"),
    ({"direction": [0.0, 1.0]}, "3 finite values"),
    ({"sample_period_s": 0.1 / 35.0 * 1.001}, "too coarse"),
    ({"max_lookahead_s": 30.0, "sample_period_s": 1e-4}, "samples"),
    ({"frequency_hz": 1e9}, "outside the vibration unit's band"),
])
def test_each_settings_rule_refuses_just_beyond_its_boundary(robot, change, words):
    """The documented rules, each at its boundary: just beyond it is refused with the reason, exactly at it
    is accepted (the boundary values: lead 0, duration 0 or 2 ramps, start_lead = lead)."""
    reason = settings_reason(robot, dict(default_settings(robot), **change))
    assert reason is not None and words in reason, reason


@pytest.mark.parametrize("change", [{"lead_s": 0.0}, {"duration_s": 0.0}, {"lead_s": 0.5, "start_lead_s": 0.5},
                                    {"ramp_s": 0.25, "duration_s": 0.5}, {"phase_rad": -1.0},
                                    {"sample_period_s": 0.1 / 35.0 * 0.999}, {"direction": [0.0, 1e-3, 0.0]}])
def test_each_settings_rule_accepts_its_boundary(robot, change):
    assert settings_reason(robot, dict(default_settings(robot), **change)) is None
