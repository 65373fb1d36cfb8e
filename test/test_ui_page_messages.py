"""What the planning page gets (ui/page_messages.py, ui/page_commands.py): the hello message, the live frame
assembled from the models (hand-computed ages, leg lengths and hinge points, plot rows taken once, JSON
round trip), the web server's backend, and the commands' answers from the core's checks."""

from __future__ import annotations

import json

import numpy as np
import pytest

from stewart_vibration.motion.paths import checked_path
from stewart_vibration.paper import paper_pose
from stewart_vibration.ui import page_commands, page_messages
from stewart_vibration.ui.command_queue import CommandInbox
from stewart_vibration.ui.live_streams import JOINTS, POSES, LiveStreams
from stewart_vibration.ui.model import pose_fields
from stewart_vibration.ui.move_follow import FollowedMove
from stewart_vibration.ui.planner_settings import PlannerSettings
from stewart_vibration.ui.suite_status import Event, SuiteStatus
from stewart_vibration.ui.vibration_follow import VibrationFollow

PAPER_FIELDS = {"x_mm": 2.0, "y_mm": 2.0, "z_mm": 162.0, "roll_deg": 12.0, "pitch_deg": 15.0, "yaw_deg": 10.0}
VIBRATION = {"direction": [0, 0, 1], "frame": "platform", "mode": "acceleration", "acceleration_g": 0.3,
             "frequency_hz": 35, "phase_deg": 0, "duration_s": 3, "ramp_s": 0.2}


def test_hello_gives_the_robot_and_the_settle_tolerance(robot):
    hello = page_messages.hello(robot, "/stewart")
    assert hello["namespace"] == "/stewart" and hello["settle"] == {"position_um": pytest.approx(10.0),
                                                                     "angle_deg": pytest.approx(0.01)}
    assert hello["robot"]["home"] == pytest.approx(pose_fields(robot.home_pose))
    assert hello["paper_pose"] == pytest.approx(PAPER_FIELDS)
    assert len(hello["robot"]["base_points_mm"]) == 6 and json.loads(json.dumps(hello)) == hello


def models(robot):
    suite = SuiteStatus("planning_ui: planning UI")
    live = LiveStreams(10.0, 250.0, lambda names: (None, None), lambda *a, **k: None)
    return suite, live, VibrationFollow(robot, live.buffers, suite.events), PlannerSettings.defaults(robot)


def test_a_frame_shows_the_latest_values_and_each_plot_row_once(robot):
    suite, live, vibration, planner = models(robot)
    level = np.array([0.001, -0.002, 0.16, 0.0, 0.0, 0.0])
    live.latest_estimate = (4.0, level)
    live.latest_joints = (4.002, np.r_[np.full(6, 0.3), np.full(6, 2e-6), np.arange(6.0), np.zeros(6)])
    live.seen.update({JOINTS: 9.75, POSES: 9.5})
    live.plots["joints"].append([4.0, *[1.234567] * 12])
    suite.events.add(Event("kinematics", "stale"))
    move = FollowedMove(level + [1e-6, 0, 0, 0, 0, 0], sent=8.0)
    frame = page_messages.frame(robot, 10.0, 1.7e9, 1.0, live, move, vibration, suite, planner)
    assert json.loads(json.dumps(frame)) == frame
    assert frame["type"] == "frame" and frame["wall"] == 1.7e9 and frame["stale_after_s"] == 1.0
    assert frame["ages"] == {JOINTS: 0.25, POSES: 0.5}
    assert frame["plots"] == {"joints": [[4.0, *[1.2346] * 12]], "forces": []}  # rounded to 4 decimals
    # a level platform: the hinge points are the platform's own, shifted by the position
    np.testing.assert_allclose(frame["estimate"]["points_mm"], (robot.platform_hinges + level[:3]) * 1e3)
    assert frame["estimate"]["fields"]["x_mm"] == pytest.approx(1.0)
    assert frame["legs"]["length_mm"] == pytest.approx([300.002] * 6)  # strut + unit
    assert frame["legs"]["vib_um"] == pytest.approx([2.0] * 6) and frame["legs"]["force_n"] == list(range(6))
    assert frame["move"]["error_um"] == pytest.approx(1.0) and frame["move"]["elapsed_s"] == 2.0
    assert frame["vibration"] is None and frame["summary"] is None and frame["planner_known"] is False
    assert frame["mcap"] == {"path": None, "state": "unknown"} and frame["report"] == []
    assert [e["text"] for e in frame["events"]] == ["stale"] and frame["nodes"] == []
    again = page_messages.frame(robot, 10.1, 1.7e9, 1.0, live, None, vibration, suite, planner)
    assert again["plots"] == {"joints": [], "forces": []} and "move" not in again


def test_the_backend_queues_commands_and_offers_only_listed_files(robot):
    inbox, suite = CommandInbox(), SuiteStatus("me")
    backend = page_messages.PageBackend({"type_of": "hello"}, inbox, suite)
    assert backend.hello() == {"type_of": "hello"}
    backend.command("move", {"x_mm": 1.0}, print)
    backend.command("estop", {}, print)
    assert list(inbox.commands) == [("move", {"x_mm": 1.0}, print)] and inbox.take_estops() == [print]
    assert backend.file("report", "a.png") is None


def test_a_pose_check_and_a_path_are_answered_from_the_core(robot):
    ok = page_commands.check_pose_answer(robot, PAPER_FIELDS)
    assert ok["ok"] and ok["message"] == "reachable" and ok["reachable"]
    far = page_commands.check_pose_answer(robot, {**PAPER_FIELDS, "z_mm": 302.0})
    assert far["ok"] and not far["reachable"] and far["message"] == far["error"]["message"]
    path = checked_path(robot, robot.home_pose, paper_pose(robot))
    answer = page_commands.path_answer(robot, "SUCCEEDED", "", list(path))
    assert answer["ok"] and answer["message"] == f"path of {len(path)} waypoints"
    assert answer["path"]["waypoints"] == len(path)
    assert page_commands.path_answer(robot, "LIMIT_EXCEEDED", "leg 3 too long", []) == {
        "ok": False, "refused_by": "kinematics", "outcome": "LIMIT_EXCEEDED",
        "message": "LIMIT_EXCEEDED: leg 3 too long", "path": {"waypoints": 0}}


def test_a_refused_move_shows_both_reasons():
    check = {"reachable": False, "error": {"type": "StrokeLimitError", "message": "leg 2 beyond", "leg": 2}}
    assert page_commands.move_refused(check, "LIMIT_EXCEEDED: leg 2") == {
        "ok": False, "refused_by": "planning_ui (core check_pose)", "error": check["error"],
        "message": "not sent: StrokeLimitError: leg 2 beyond", "node_reason": "LIMIT_EXCEEDED: leg 2", "check": check}


def test_a_start_is_refused_while_moving_or_infeasible(robot):
    planner = PlannerSettings.defaults(robot)
    _, settings = planner.vibration(robot, VIBRATION)
    pose = paper_pose(robot)
    moving = FollowedMove(pose, sent=0.0)
    preview, refused = page_commands.start_check(robot, pose, settings, planner, moving, now=1.0)
    assert preview == {} and refused["message"].startswith("not started: the platform is still moving")
    preview, refused = page_commands.start_check(robot, pose, settings, planner, moving, now=121.0)
    assert refused is None and preview["feasible"]
    _, strong = planner.vibration(robot, {**VIBRATION, "acceleration_g": 3.0})
    preview, refused = page_commands.start_check(robot, pose, strong, planner, None, now=0.0)
    assert refused == {"ok": False, "refused_by": "planning_ui (core checks)",
                       "message": f"not started: {preview['reason']}", "preview": preview}
    assert "VibrationLimitError" in preview["reason"]
    answer = page_commands.preview_answer(robot, pose, strong, planner)
    assert answer["ok"] is True and answer["message"] == preview["reason"]  # a preview is answered either way
    assert answer["planner_settings_known"] is False


def test_a_stop_says_how_many_vibrations_ramp_out():
    assert page_commands.cancel_answer(True, 2) == {"ok": True,
                                                    "message": "cancelling 2 vibration(s): the units ramp out"}
    assert page_commands.cancel_answer(False, 0) == {"ok": True, "message": "no vibration is running"}
    assert page_commands.cancel_answer(False, 1)["ok"] is False
