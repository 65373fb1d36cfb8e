"""vibration.start_gate: each reason a vibration cannot start now, with its outcome name, and none when it can."""

from __future__ import annotations

import pytest

from stewart_vibration.errors import RefusedError
from stewart_vibration.vibration.start_gate import CLOCK_MISMATCH_S, check_can_start

READY = dict(planner_state="idle", units_state="idle", status_age_s=0.2, status_stale_s=2.5, robot_time_s=100.0,
             now_s=100.3, pose_age_s=0.01, pose_timeout_s=1.0, clock_rate=1.0)


def refusal(**change) -> str | None:
    try:
        check_can_start(**{**READY, **change})
    except RefusedError as exc:
        assert str(exc)  # every refusal says why
        return exc.outcome
    return None


def test_a_ready_robot_may_start():
    assert refusal() is None
    assert refusal(planner_state="aborted: the units stopped") is None  # an abort latches nothing


@pytest.mark.parametrize("change, outcome", [
    ({"planner_state": "running"}, "BUSY"),
    ({"planner_state": "stopping"}, "BUSY"),
    ({"units_state": "estopped"}, "ESTOP_LATCHED"),
    ({"units_state": "estopped", "status_age_s": 60.0}, "ESTOP_LATCHED"),  # a latch holds however old its word
    ({"units_state": "ramping_out"}, "UNITS_NOT_AT_REST"),
    ({"units_state": "pending"}, "UNITS_NOT_AT_REST"),
    ({"robot_active": False}, "ROBOT_INACTIVE"),  # the emulator deactivated (lifecycle): it refuses commands
    ({"now_s": 0.0}, "CLOCK_NOT_RUNNING"),
    ({"now_s": 1.8e9}, "CLOCK_MISMATCH"),  # a planner on the wall clock beside a robot on sim time
    # the robot's state cannot be confirmed: no status yet, or one too old to say anything about now (a
    # planner on the wall clock beside a sim-time robot would otherwise pass unchecked)
    ({"units_state": None, "robot_time_s": None}, "NOT_READY"),
    ({"units_state": None, "robot_time_s": None, "now_s": 1.8e9}, "NOT_READY"),
    ({"units_state": "running", "status_age_s": 5.0}, "NOT_READY"),
    ({"robot_active": False, "status_age_s": 5.0}, "NOT_READY"),
    ({"now_s": 1.8e9, "status_age_s": 5.0}, "NOT_READY"),
    ({"pose_age_s": None}, "NOT_READY"),
    ({"pose_age_s": 1.5}, "NOT_READY"),
])
def test_each_reason_has_its_outcome(change, outcome):
    assert refusal(**change) == outcome


def test_a_clock_running_faster_than_real_time_is_the_same_clock():
    """At 20x real time a 1 s old status lags the robot's clock by 20 s: that is no mismatch."""
    assert refusal(now_s=100.0 + 20.0, status_age_s=1.0, clock_rate=20.0) is None
    assert refusal(now_s=100.0 + CLOCK_MISMATCH_S + 1.0, status_age_s=0.0, clock_rate=1.0) == "CLOCK_MISMATCH"


def report(**fields):
    from stewart_vibration.emulation.vibration_status import VibrationReport

    return VibrationReport(**{"state": "running", "level": "ok", "reason": "", "since": 10.0, "time": 10.5,
                              **fields})


T0 = 10.0


@pytest.mark.parametrize("fields, new_event, outcome", [
    ({}, False, None),  # running as started
    ({"state": "idle", "since": 9.0}, False, None),  # idle from before the run: not a stop
    ({"event": "refused", "event_stamp": T0 + 0.87, "event_outcome": "LIMIT_EXCEEDED"}, True, "ROBOT_REFUSED"),
    ({"event": "refused", "event_stamp": T0 + 0.87}, False, None),  # an event seen already
    ({"event": "refused", "event_stamp": T0 - 5.0}, True, None),  # a window of an earlier run
    ({"state": "estopped"}, False, "EMERGENCY_STOPPED"),
    ({"state": "estopped", "fault": "qacc diverged"}, False, "PHYSICS_FAULT"),
    ({"state": "stopped", "since": 10.4, "event": "safety_ramp", "event_outcome": "UNIT_TRAVEL_STOPPED"}, True,
     "UNIT_TRAVEL_STOPPED"),
    ({"state": "stopped", "since": 10.4, "event": "accepted"}, False, "STOPPED_EARLY"),
    ({"state": "stopped", "since": 9.5}, False, None),  # stopped before this run began
])
def test_the_robot_stopping_a_run_is_named_by_its_outcome(fields, new_event, outcome):
    from stewart_vibration.vibration.start_gate import robot_stop

    stop = robot_stop(report(**fields), T0, new_event)
    assert (None if stop is None else stop[0]) == outcome
    assert stop is None or stop[1]  # every stop says why
