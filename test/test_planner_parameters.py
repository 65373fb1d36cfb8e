"""vibration.planner_parameters: a change of the planner's parameters is judged on the settings as they would
be (the streaming's rules), names that are no setting pass through, and a new identification_file is read once
-- what a saved identification holds comes back -- or refused with why."""

from __future__ import annotations

import numpy as np
import pytest
from test_compensation import linear_identification

from stewart_vibration.paper import paper_pose
from stewart_vibration.vibration.planner_parameters import parameter_change
from stewart_vibration.vibration.settings import default_settings
from stewart_vibration.vibration.unit_identification import save_identification


@pytest.fixture
def settings(robot):
    return default_settings(robot)  # window_period_s 0.5, lookahead_s 2.0


def test_the_streamings_rules_judge_the_settings_as_they_would_be(robot, settings):
    assert parameter_change(robot, settings, {"lead_s": 0.2, "loop_gain": 0.3}) == ("", None)
    reason, read = parameter_change(robot, settings, {"lookahead_s": 0.4})  # not longer than the window period
    assert "lookahead_s" in reason and read is None
    assert parameter_change(robot, settings, {"lookahead_s": 0.4, "window_period_s": 0.2}) == ("", None)
    assert settings["lookahead_s"] == 2.0  # the settings passed in stay as they are
    reason, _ = parameter_change(robot, settings, {"lead_s": "soon"})
    assert reason.startswith("invalid parameter value: ")


def test_a_new_identification_file_is_read_once_and_what_it_holds_comes_back(robot, settings, tmp_path):
    assert parameter_change(robot, settings, {"identification_file": ""}) == ("", ("", None))
    saved = linear_identification(robot, paper_pose(robot))
    path = str(save_identification(tmp_path / "ident.yaml", saved))
    reason, (read_path, ident) = parameter_change(robot, settings, {"identification_file": path})
    assert reason == "" and read_path == path
    np.testing.assert_allclose(ident.platform_response, saved.platform_response)
    np.testing.assert_allclose(ident.frequencies, saved.frequencies)
    missing = str(tmp_path / "missing.yaml")
    reason, read = parameter_change(robot, settings, {"identification_file": missing})
    assert reason.startswith("identification_file: ") and read is None
    reason, read = parameter_change(robot, settings, {"identification_file": path, "lookahead_s": 0.4})
    assert "lookahead_s" in reason and read is None  # refused on the settings: the file is not read
