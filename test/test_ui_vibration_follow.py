"""The planning page's vibration following (ui/vibration_follow.py) with stepped reports: the events a
vibration/status report is worth, which vibration is followed and whose it is, the run summary once the units
rest after its t0 (from the full-rate buffers, of a vibration as planned), the page's view, and the start
command answered once."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from stewart_vibration.emulation.vibration_status import VibrationReport
from stewart_vibration.kinematics import inverse_kinematics
from stewart_vibration.paper import paper_pose
from stewart_vibration.robot import STANDARD_GRAVITY
from stewart_vibration.ui.live_streams import RunBuffers
from stewart_vibration.ui.model import StreamBuffer
from stewart_vibration.ui.suite_status import Event, EventLog, NodeStatus
from stewart_vibration.ui.vibration_follow import (
    DeliveredFigures,
    StartAnswer,
    VibrationFollow,
    status_events,
)
from stewart_vibration.vibration.settings import default_settings, plan_vibration
from stewart_vibration.vibration.signals import platform_vibration_motion, sample_leg_vibration

T0 = 10.0  # the vibration's start (sim s)
RATE = 500.0


def report(state="running", since=T0, time=T0 + 1.0, **fields):
    return VibrationReport(state=state, level="ok", since=since, time=time, **{"reason": "", **fields})


def empty_buffers():
    return RunBuffers(StreamBuffer(60.0), StreamBuffer(60.0), StreamBuffer(60.0))


def follower(robot, buffers=None):
    events = EventLog(wall_clock=iter(range(1000, 2000)).__next__)
    return VibrationFollow(robot, buffers or empty_buffers(), events), events


def plan(t0=T0, amplitude_m=50e-6):
    return {"t0_s": t0, "pose": [0.0, 0.0, 0.16, 0.0, 0.0, 0.0], "frequency_hz": 35.0, "amplitude_m": amplitude_m,
            "direction_base": [0.0, 0.0, 1.0], "leg_amplitudes_m": [20e-6] * 6}


DELIVERED = DeliveredFigures(1.5, 35.0, 49e-6, math.radians(0.5), math.radians(2.0))


def test_a_status_report_is_worth_an_event_when_something_went_wrong():
    idle = report("idle")
    assert status_events(None, report("estopped")) == []  # what came before the first report is not known
    refused = report("running", event_seq=4, event="refused", event_outcome="LIMIT_EXCEEDED", event_reason="fast")
    assert status_events(report("running", event_seq=3), refused) == [
        Event("hardware_emulator", "vibration units: refused (LIMIT_EXCEEDED): fast", "WARN")]
    assert status_events(refused, refused) == []  # the same event, told again
    assert status_events(idle, report("stopped", reason="watchdog")) == [
        Event("hardware_emulator", "vibration units stopped: watchdog", "WARN")]
    assert status_events(idle, report("estopped")) == [Event("hardware_emulator", "vibration units estopped",
                                                             "ERROR")]
    assert status_events(idle, report("running")) == []


def test_a_new_plan_is_followed_and_known_as_this_page_s_only_by_its_goal_id(robot):
    follow, _ = follower(robot)
    follow.on_feedback(plan(), {"frequency_hz": 35.0}, b"other", DELIVERED)
    assert follow.run.source == "another client" and not follow.following_own_run
    follow.sent(b"mine")
    follow.on_feedback(plan(T0 + 5e-7), {"frequency_hz": 35.0}, b"mine", DELIVERED)  # the same vibration
    assert follow.run.source == "another client"
    follow.on_feedback(plan(T0 + 20.0), {"frequency_hz": 40.0}, b"mine", DELIVERED)
    assert follow.run.source == "this page" and follow.run.t0 == T0 + 20.0 and follow.following_own_run
    assert follow.run.settings == {"frequency_hz": 40.0} and follow.delivered is DELIVERED
    np.testing.assert_array_equal(follow.run.nominal, [0.0, 0.0, 0.16, 0.0, 0.0, 0.0])


def test_the_run_ends_once_when_the_units_rest_after_its_t0(robot):
    follow, events = follower(robot)
    follow.on_feedback(plan(), dict(default_settings(robot), duration_s=2.0), b"x", DELIVERED)
    follow.on_status(report("running", since=T0))
    follow.on_status(report("idle", since=T0 - 3.0, time=T0 - 0.5))  # a report from before the start
    assert not follow.run.done and follow.summary is None
    follow.on_status(report("ramping_out", since=T0 + 2.0, time=T0 + 2.1))
    assert not follow.run.done
    follow.on_status(report("stopped", since=T0 + 2.2, time=T0 + 2.3))
    # nothing was recorded: the page is told why there is no summary
    assert follow.run.done and follow.summary["t0_s"] == T0 and follow.summary["ended_s"] == T0 + 2.2
    assert follow.summary["error"].startswith("ValueError")
    assert [e["text"] for e in events.view()] == ["vibration units stopped"]
    follow.on_status(report("idle", since=T0 + 2.5, time=T0 + 2.6))
    assert follow.summary["ended_s"] == T0 + 2.2  # summarised once


def recorded_vibration(robot, settings):
    """The full-rate buffers of a vibration that ran exactly as planned at the paper's pose from T0."""
    pose0 = paper_pose(robot)
    planned = plan_vibration(robot, pose0, settings, check_limits=False, method="linear")
    duration, ramp = settings["duration_s"], settings["ramp_s"]
    t = T0 - 1.0 + np.arange(int((duration + 2.0) * RATE)) / RATE
    vib = sample_leg_vibration(robot, planned, t - T0, duration=duration, ramp_time=ramp, method="linear").position
    motion = platform_vibration_motion(planned, t - T0, duration=duration, ramp_time=ramp)
    struts = np.broadcast_to(inverse_kinematics(robot, pose0), vib.shape)
    effort = 40.0 + 3.0 * np.sin(2 * np.pi * settings["frequency_hz"] * t)[:, None] * np.ones(6)
    buffers = empty_buffers()
    buffers.joints.add(t, np.hstack([struts, vib, effort, effort]))
    buffers.poses.add(t, motion.pose)
    buffers.forces.add(t, effort)
    return buffers


def test_the_summary_of_a_vibration_as_planned_shows_its_planned_amplitude(robot):
    settings = dict(default_settings(robot), duration_s=3.0)  # 0.3 g at 35 Hz along the tibia axis
    follow, _ = follower(robot, recorded_vibration(robot, settings))
    follow.sent(b"mine")
    follow.on_feedback({"t0_s": T0, "pose": paper_pose(robot)}, settings, b"mine", DELIVERED)
    follow.on_status(report("idle", since=T0 + 3.0, time=T0 + 3.1))
    summary = follow.summary
    amplitude_um = 0.3 * STANDARD_GRAVITY / (2 * math.pi * 35.0) ** 2 * 1e6  # a = A w^2
    assert "error" not in summary and summary["source"] == "this page"
    assert summary["planned_amplitude_um"] == pytest.approx(amplitude_um, rel=1e-9)
    assert summary["measured_amplitude_um"] == pytest.approx(amplitude_um, rel=1e-3)
    assert summary["direction_error_deg"] < 0.01 and summary["frequency_hz"] == 35.0


def test_the_view_shows_the_units_the_planner_and_what_was_delivered(robot):
    follow, _ = follower(robot)
    assert follow.view(None) is None
    follow.on_status(report("estopped", amplitude=np.full(6, 2e-6), accepted=3, refused=1))
    view = follow.view(None)
    assert view["estopped"] and view["amplitude_um"] == pytest.approx([2.0] * 6)
    assert (view["accepted"], view["refused"], view["planner"], view["delivered"]) == (3, 1, None, None)
    follow.on_feedback(plan(), {}, b"x", DELIVERED)
    view = follow.view(NodeStatus(0, "vibrating", {"state": "streaming"}, 1.0))
    assert (view["planner"], view["planner_message"]) == ("streaming", "vibrating")
    assert view["delivered"] == {"elapsed_s": 1.5, "frequency_hz": 35.0, "amplitude_um": pytest.approx(49.0),
                                 "direction_error_deg": pytest.approx(0.5), "phase_spread_deg": pytest.approx(2.0)}


def test_delivered_figures_are_read_from_the_feedback_by_name():
    feedback = SimpleNamespace(elapsed_s=1.5, frequency_hz=35.0, delivered_amplitude_m=49e-6,
                               direction_error_rad=math.radians(0.5), phase_spread_rad=math.radians(2.0))
    assert DeliveredFigures.of(feedback) == DELIVERED


def test_the_start_is_answered_once_by_its_first_feedback():
    replies = []
    start = StartAnswer(replies.append, {"leg_amplitudes_um": [20.0, 20.0, 20.0, 20.0, 20.0, 20.5]})
    event = start.started(plan())
    text = "started: 35 Hz, platform amplitude 50.000 um along [0.0, 0.0, 1.0] (base frame), t0 = 10.000000 s"
    assert event == Event("vibration_planner", text, "OK")
    assert replies == [{"ok": True, "message": text, "plan": plan(), "preview": start.preview,
                        "preview_vs_plan_um": pytest.approx(0.5)}]
    assert start.started(plan()) is None  # later feedback: answered already
    assert start.ended("STOPPED_EARLY", "cancelled") == Event("vibration_planner", "STOPPED_EARLY: cancelled",
                                                              "WARN")
    assert start.ended("SUCCEEDED", "") is None and len(replies) == 1


def test_a_start_the_planner_refused_is_answered_with_its_outcome():
    replies = []
    refused = StartAnswer(replies.append, {"feasible": True})
    assert refused.ended("LIMIT_EXCEEDED", "too fast") == Event("vibration_planner", "LIMIT_EXCEEDED: too fast",
                                                                "WARN")
    assert replies == [{"ok": False, "refused_by": "vibration_planner", "outcome": "LIMIT_EXCEEDED",
                        "message": "too fast", "preview": {"feasible": True}}]
    untaken = StartAnswer(replies.append, {})
    untaken.not_accepted()
    untaken.not_accepted()
    assert replies[1:] == [{"ok": False, "refused_by": "vibration_planner", "message": "the goal was not accepted"}]
