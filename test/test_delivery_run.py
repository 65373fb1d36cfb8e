"""vibration.delivery_run driven with stepped time (no ROS): t0 and the first window, the windows every
window_period_s, the feedback every 0.1 wall s, the ends (the robot's word needed for a success, a cancel's
ramp-out, a stall past the look-ahead, the robot's stops and an early idle), the dose in closed form (the quintic
ramps' integrals are half their length), and the closed loop's abort when the IMU stays silent."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from test_compensation import linear_identification

from stewart_vibration.emulation.vibration_status import VibrationReport
from stewart_vibration.paper import paper_pose
from stewart_vibration.vibration.delivery_run import NEVER_CONFIRMED, LoopSettings, start_delivery
from stewart_vibration.vibration.settings import default_settings, same_seconds

F, RAMP, LEAD, LOOKAHEAD, PERIOD, START_LEAD = 35.0, 0.2, 0.3, 2.0, 0.5, 1.0
TICK = 0.01  # s of the clock (and of the wall clock) between ticks
NOW = 100.0  # the clock (s) when a goal arrives
WALL = 5000.0  # the wall clock (s) then


def start(robot, pose_stamp=NOW, seen_event=0, identification=None, loop=None, **vibration):
    s = default_settings(robot)
    s.update(direction=[0.0, 0.0, 1.0], frame="platform", acceleration_g=0.3, frequency_hz=F, ramp_s=RAMP,
             duration_s=0.0, lead_s=LEAD, lookahead_s=LOOKAHEAD, window_period_s=PERIOD, start_lead_s=START_LEAD)
    s.update(vibration)
    return start_delivery(robot, paper_pose(robot), pose_stamp, NOW, s, same_seconds, seen_event, identification,
                          loop)


def ms_ceil(t: float) -> float:
    """The first 1 ms sample at or after ``t`` (s)."""
    return math.ceil(round(t * 1000, 6)) / 1000


def run_until(run, rel_end: float):
    """Tick every TICK from the last tick (the start at first) until ``rel_end`` s from t0 or the run's end:
    (clock s, wall s, step) of every tick that did something. The wall clock runs as the clock, from WALL."""
    done, first = [], run.t0 + run.seen
    for k in range(1, 100_000):
        now = first + k * TICK
        wall = WALL + (now - NOW)
        if now - run.t0 > rel_end + 1e-9:
            return done
        step = run.tick(now, wall)
        if step.feedback or step.window is not None or step.end is not None:
            done.append((now, wall, step))
        if step.end is not None:
            run.ended = now
            return done
    raise AssertionError("the run never got there")


def report(state, since, event_seq=0, event="", event_stamp=None, outcome="", fault="", reason=""):
    return VibrationReport(state=state, level="ok", reason=reason, since=since, time=since, event_seq=event_seq,
                           event=event, event_stamp=event_stamp, event_outcome=outcome, event_reason=reason,
                           fault=fault)


def test_t0_follows_the_fresher_pose_stamp_and_the_first_window_ramps_in_from_rest(robot):
    run, first, summary = start(robot, pose_stamp=NOW + 0.25)  # resumed from a stall: the clock lags the pose
    assert run.t0 == pytest.approx(NOW + 0.25 + START_LEAD)
    assert run.next_send == pytest.approx(NOW + 0.25 + PERIOD) and run.seen == pytest.approx(-START_LEAD)
    assert first.times[0] == 0.0 and first.times[-1] == pytest.approx(LOOKAHEAD + RAMP)  # vibration, then its tail
    np.testing.assert_allclose(first.position[0], 0.0, atol=1e-15)
    assert f"t0 = {run.t0:.6f} s" in summary and "until cancelled" in summary and "uncompensated" in summary
    assert run.loop is None and not run.listens_to_imu and run.loop_figures() == (0, 0.0)


def test_windows_every_period_each_lead_s_ahead_and_feedback_every_tenth_of_a_wall_second(robot):
    run, _, _ = start(robot)
    done = run_until(run, 2.95)  # 3.95 s after the start: 7 periods and 7 ticks' lateness at most
    sent = [(now, step.window) for now, _, step in done if step.window is not None]
    sends = [NOW] + [now for now, _ in sent]
    gaps = np.diff(sends)
    assert len(sent) == 7 and np.all(gaps >= PERIOD - 1e-9) and np.all(gaps <= PERIOD + TICK + 1e-9)
    for now, window in sent:
        start_at = ms_ceil(max(now - run.t0 + LEAD, 0.0))
        assert window.times[0] == pytest.approx(start_at) and not window.final
        assert window.times[-1] == pytest.approx(ms_ceil(start_at + LOOKAHEAD) + RAMP)
    feedback = [wall for _, wall, step in done if step.feedback]
    assert feedback[0] == pytest.approx(WALL + TICK)  # at once, then every 0.1 s of the wall clock
    assert np.all(np.diff(feedback) >= 0.1 - 1e-9) and np.all(np.diff(feedback) <= 0.1 + TICK + 1e-9)
    assert not any(step.end for _, _, step in done)


@pytest.mark.parametrize("confirmed", [False, True])
def test_a_vibration_sent_whole_succeeds_at_its_end_only_when_the_robot_said_its_units_moved(robot, confirmed):
    run, first, summary = start(robot, duration_s=1.0)
    assert first.final and run.stream.finished and "(sent whole)" in summary
    if confirmed:
        assert run.on_status(report("running", run.t0 + 0.01)) is None and run.confirmed
    done = run_until(run, 2.0)
    assert not [step for _, _, step in done if step.window is not None]
    now, _, last = done[-1]
    assert now - run.t0 >= 1.0 - 1e-9 and now - run.t0 < 1.0 + TICK  # the first tick at the planned end
    if confirmed:
        assert (last.end.outcome, last.end.aborted) == ("SUCCEEDED", False)
    else:
        assert (last.end.outcome, last.end.message, last.end.aborted) == ("STOPPED_EARLY", NEVER_CONFIRMED, True)
    active, cycles = run.delivered_dose()
    assert active == pytest.approx(1.0) and cycles == pytest.approx(F * (1.0 - RAMP), rel=1e-5)


def test_a_cancel_ramps_out_lead_s_ahead_and_ends_cancelled_at_rest(robot):
    run, _, _ = start(robot)
    run_until(run, 1.0)
    stop = run.stop(run.t0 + 1.0)
    assert run.stopping and stop.window is not None and stop.window.final
    assert stop.window.times[0] == pytest.approx(1.0 + LEAD) and stop.window.rest_at == pytest.approx(1.0 + LEAD + RAMP)
    np.testing.assert_allclose(stop.window.position[-1], 0.0, atol=1e-12)
    assert stop.message == (f"stopping: ramp-out from {run.t0 + 1.3:.4f} s over {RAMP} s, at rest at "
                            f"{run.t0 + 1.5:.4f} s")
    done = run_until(run, 3.0)
    assert not [step for _, _, step in done if step.window is not None]
    now, _, last = done[-1]
    assert (last.end.outcome, last.end.aborted) == ("CANCELED", False) and 1.5 <= now - run.t0 < 1.5 + TICK
    active, cycles = run.delivered_dose()  # ramp-in R/2, steady 1.3 - R, ramp-out R/2
    assert active == pytest.approx(1.5) and cycles == pytest.approx(F * 1.3, rel=1e-5)


def test_a_cancel_before_t0_keeps_the_units_at_rest(robot):
    run, _, _ = start(robot)
    stop = run.stop(run.t0 - 0.9)
    assert stop.window is not None and not stop.window.position.any() and stop.window.times[0] == 0.0
    assert stop.message == f"stopping before the vibration began at {run.t0:.4f} s: the units stay at rest"
    assert run.tick(run.t0 + RAMP, WALL).end.outcome == "CANCELED"


def test_a_stall_past_the_buffered_look_ahead_is_held_up_and_a_shorter_one_is_not(robot):
    run, _, _ = start(robot)
    run_until(run, 1.0)
    tail = run.stream.tail_start  # where the last window's ramp-out begins (s from t0)
    margin = tail - run.seen - LEAD  # a window sent later than this would start inside that ramp-out
    assert run.after_stall(margin - 0.002).end is None
    held_up = run.after_stall(margin + 0.002).end
    assert held_up.outcome == "HELD_UP" and held_up.aborted and "held up" in held_up.message
    whole, _, _ = start(robot, duration_s=1.0)
    assert whole.after_stall(100.0).end is None  # sent whole: no window left to be late


def test_the_robots_word_ends_the_run_with_its_outcome(robot):
    run, _, _ = start(robot, seen_event=7)
    t0 = run.t0
    refused = report("pending", t0 - 1, event_seq=7, event="refused", event_stamp=t0, outcome="LIMIT_EXCEEDED")
    assert run.on_status(refused) is None  # event 7 was the robot's last before this run: not this run's
    end = run.on_status(replace(refused, event_seq=8))
    assert (end.outcome, end.aborted, end.emergency) == ("ROBOT_REFUSED", True, False)
    assert run.on_status(report("estopped", t0 + 0.1)).emergency
    assert run.on_status(report("estopped", t0 + 0.1, fault="diverged")).outcome == "PHYSICS_FAULT"
    ramp = report("stopped", t0 + 0.2, event_seq=9, event="safety_ramp", outcome="UNIT_TRAVEL_STOPPED")
    assert run.on_status(ramp).outcome == "UNIT_TRAVEL_STOPPED"
    early = run.on_status(report("idle", t0 + 0.5, reason="deactivated"))
    assert early.outcome == "STOPPED_EARLY" and "until stop" in early.message and "deactivated" in early.message


def test_an_idle_robot_ends_a_finite_run_early_only_before_its_planned_end(robot):
    run, _, _ = start(robot, duration_s=1.0)
    t0 = run.t0
    early = run.on_status(report("idle", t0 + 0.9))
    assert early.outcome == "STOPPED_EARLY" and f"({t0 + 1.0:.3f} s)" in early.message
    assert run.on_status(report("idle", t0 + 0.96)) is None  # within the robot's tick of the end: that end
    assert run.on_status(report("idle", t0 - 0.5)) is None  # idle since before t0: not yet begun
    run.stop(t0 + 0.1)
    assert run.on_status(report("idle", t0 + 0.5)) is None  # a cancel's ramp-out ends idle


def test_the_closed_loop_aborts_after_a_silent_imu_with_a_stop_window(robot):
    pose = paper_pose(robot)
    loop = LoopSettings(gain=0.5, imu_average_s=0.0, imu_silence_s=0.1)
    run, _, summary = start(robot, identification=linear_identification(robot, pose), loop=loop)
    assert run.loop is not None and run.listens_to_imu and "closed loop on the platform IMU" in summary
    assert "non-finite" in run.add_imu(run.t0, [np.nan, 0.0, 0.0], [0.0, 0.0, 0.0])
    done = run_until(run, 2.0)
    now, _, last = done[-1]
    assert last.end.outcome == "DELIVERY_LIMIT" and "went silent" in last.end.message
    assert RAMP + 0.1 - 1e-9 < now - run.t0 <= RAMP + 0.1 + TICK + 1e-9  # the first tick past the ramp, the silence
    assert last.stop is not None and last.stop.window is not None and run.stopping
    assert not run.listens_to_imu and run.add_imu(now, [np.nan] * 3, [0.0] * 3) == ""  # ramping out: not heard
    assert run.loop_figures() == (0, 0.0)


def test_a_closed_loop_needs_the_identification(robot):
    run, _, summary = start(robot, loop=LoopSettings(0.5, 0.0, 0.1))
    assert run.loop is None and "no closed loop: it needs the units' identification at this pose" in summary
