"""The planning page's move following (ui/move_follow.py) with stepped stamps: settled only after the pose
estimate held within 10 um / 0.01 deg of the target for 0.5 s of its stamps (a blip starts the hold over,
angles compare wrapped), what the goal's feedback and result say, and the page's view of it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from stewart_vibration.ui.move_follow import MOVE_TIMEOUT_S, FollowedMove
from stewart_vibration.ui.suite_status import Event

TARGET = np.array([0.002, 0.002, 0.162, 0.2, 0.25, 0.17])
NEAR = TARGET + [5e-6, 0, 0, 0, 0, 0]  # 5 um off: within
FAR = TARGET + [2e-5, 0, 0, 0, 0, 0]  # 20 um off: outside
TILTED = TARGET + [0, 0, 0, math.radians(0.02), 0, 0]  # 0.02 deg off: outside


def feed(move, start, count, pose, now, step=0.05):
    """``count`` estimates of ``pose`` from stamp ``start`` every ``step`` s, in one batch."""
    stamps = start + step * np.arange(count)
    move.follow(stamps, np.tile(pose, (count, 1)), now)
    return stamps[-1]


def test_a_move_settles_after_holding_half_a_second_across_batches():
    move = FollowedMove(TARGET, sent=100.0)
    feed(move, 0.0, 5, FAR, now=100.5)  # stamps 0.0 .. 0.2
    assert move.status == "moving" and move.held.since is None
    feed(move, 0.25, 5, NEAR, now=101.0)  # 0.25 .. 0.45: held from 0.25
    assert move.moving and move.held.since == pytest.approx(0.25)
    feed(move, 0.5, 5, NEAR, now=101.5)  # 0.5 .. 0.7: 0.45 s held
    assert move.moving
    feed(move, 0.75, 3, NEAR, now=102.25)  # 0.75: 0.5 s held
    assert move.status == "settled" and move.settled_after_s == pytest.approx(2.25)
    feed(move, 0.9, 3, FAR, now=103.0)  # once settled, later estimates change nothing
    assert move.status == "settled" and move.settled_after_s == pytest.approx(2.25)


def test_an_estimate_outside_the_tolerance_starts_the_hold_over():
    move = FollowedMove(TARGET, sent=0.0)
    feed(move, 0.0, 7, NEAR, now=1.0)  # 0.0 .. 0.3
    feed(move, 0.35, 1, TILTED, now=1.0)  # the angle leaves the tolerance
    feed(move, 0.4, 10, NEAR, now=1.0)  # 0.4 .. 0.85
    assert move.moving and move.held.since == pytest.approx(0.4)
    feed(move, 0.9, 1, NEAR, now=2.0)
    assert move.status == "settled"


def test_angles_are_compared_wrapped():
    target = np.array([0, 0, 0.16, 0, 0, math.pi - 1e-7])
    move = FollowedMove(target, sent=0.0)
    feed(move, 0.0, 11, [0, 0, 0.16, 0, 0, -math.pi + 1e-7], now=1.0)  # 2e-7 rad apart across +-pi
    assert move.status == "settled"


def test_a_start_waits_for_the_move_for_at_most_the_time_out():
    move = FollowedMove(TARGET, sent=10.0)
    assert move.blocks_start(10.0 + MOVE_TIMEOUT_S - 0.01)
    assert not move.blocks_start(10.0 + MOVE_TIMEOUT_S)
    move.not_taken()
    assert not move.blocks_start(10.5) and move.reason == "kinematics did not take the goal"


def test_the_result_ends_the_move_only_when_it_did_not_succeed():
    move = FollowedMove(TARGET, sent=0.0)
    assert move.ended({"outcome": "SUCCEEDED", "message": "", "peak_force_n": 12.5}) is None
    assert move.moving and (move.outcome, move.peak_force_n) == ("SUCCEEDED", 12.5)
    event = move.ended({"outcome": "GUARD_STOPPED", "message": "load 80 N", "peak_force_n": 80.0})
    assert event == Event("kinematics", "move GUARD_STOPPED: load 80 N", "WARN")
    assert (move.status, move.reason, move.peak_force_n) == ("ended GUARD_STOPPED", "load 80 N", 80.0)


def test_the_view_shows_what_was_said_and_the_estimate_s_error():
    move = FollowedMove(np.array([0.0, 0.0, 0.16, 0.0, 0.0, 0.0]), sent=5.0)
    view = move.view(7.5, None)
    # the page tests whether progress is there: nothing the goal has not said yet is sent
    assert view == {"target": {"x_mm": 0.0, "y_mm": 0.0, "z_mm": 160.0, "roll_deg": 0.0, "pitch_deg": 0.0,
                               "yaw_deg": 0.0}, "status": "moving", "held_since": None, "elapsed_s": 2.5}
    move.progressed(0.25)
    view = move.view(8.0, [3e-6, -1e-6, 0.16, 0.0, 0.001, 0.0])
    assert view["progress"] == 0.25 and "reason" not in view and "settled_after_s" not in view
    assert view["error_um"] == pytest.approx(3.0) and view["error_deg"] == pytest.approx(0.0572957795)
    assert move.sent_event() == Event("planning_ui", "move goal sent: x_mm 0.000, y_mm 0.000, z_mm 160.000, "
                                      "roll_deg 0.000, pitch_deg 0.000, yaw_deg 0.000", "OK")
