"""runtime.rest_check: the robot is at rest once no vibrate goal is open, the units are idle and the pose has
held still for the hold time -- a vibration waiting for its t0 (idle units, still platform) is not rest."""

from __future__ import annotations

import numpy as np

from stewart_vibration.runtime.rest_check import RestCheck

POSE = np.array([0.0, 0.0, 0.2, 0.0, 0.0, 0.0])


def feed(check, times, goal_open=lambda t: False, state=lambda t: "idle", pose=lambda t: POSE):
    """The first time (s) the check says rest, or None."""
    for t in times:
        if check.update(goal_open(t), state(t), pose(t), t):
            return t
    return None


def test_a_still_idle_robot_is_at_rest_after_the_hold():
    assert abs(feed(RestCheck(0.5), np.arange(0.0, 2.0, 0.01)) - 0.5) < 0.011


def test_a_goal_waiting_for_its_t0_is_not_rest_until_it_has_ended():
    """Idle units, a still platform, and a goal open until 1.2 s (its cancel's result): rest from 1.7 s."""
    at = feed(RestCheck(0.5), np.arange(0.0, 3.0, 0.01), goal_open=lambda t: t < 1.2)
    assert abs(at - 1.7) < 0.011


def test_running_units_or_a_moving_platform_are_not_rest():
    assert feed(RestCheck(0.5), np.arange(0.0, 2.0, 0.01), state=lambda t: "running") is None
    assert feed(RestCheck(0.5), np.arange(0.0, 2.0, 0.01), state=lambda t: "stopping") is None
    # a platform drifting 1 mm/s leaves any still band; once it stops at 1 s, rest comes 0.5 s later
    at = feed(RestCheck(0.5), np.arange(0.0, 3.0, 0.01),
              pose=lambda t: POSE + np.array([min(t, 1.0) * 1e-3, 0, 0, 0, 0, 0]))
    assert at is not None and 1.5 - 0.011 < at < 1.5 + 0.05
    # no pose or no clock yet: nothing can be said
    check = RestCheck(0.0)
    assert not check.update(False, "idle", None, 1.0) and not check.update(False, "idle", POSE, None)
    # before the units' first report, the goal and the pose decide
    assert RestCheck(0.0).update(False, None, POSE, 1.0)
