"""The planning UI without ROS: the page model's checks and the web server's token, routes,
rate limit and frames; plus the node's start-up refusal of a taken port (one line, exit code 2)."""

from __future__ import annotations

import json
import math
import socket
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request

import numpy as np
import pytest
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from stewart_vibration import decompose_vibration
from stewart_vibration.errors import InvalidInputError
from stewart_vibration.motion.paths import checked_path
from stewart_vibration.paper import paper_pose
from stewart_vibration.rate_limit import RateLimiter
from stewart_vibration.runtime.processes import ros_environment
from stewart_vibration.ui import STATIC_DIR, model
from stewart_vibration.ui.server import PortInUseError, UiServer, bind

PAPER_FIELDS = {"x_mm": 2.0, "y_mm": 2.0, "z_mm": 162.0, "roll_deg": 12.0, "pitch_deg": 15.0, "yaw_deg": 10.0}
VIBRATION = {"direction": [0, 0, 1], "frame": "platform", "mode": "acceleration", "acceleration_g": 0.3,
             "frequency_hz": 35, "phase_deg": 0, "duration_s": 3, "ramp_s": 0.2}


# -- model --------------------------------------------------------------------------------------------
def test_pose_fields_round_trip_and_refuse_bad_input(robot):
    pose = model.pose_from_fields(PAPER_FIELDS)
    np.testing.assert_allclose(pose, paper_pose(robot), atol=1e-12)
    assert model.pose_fields(pose) == pytest.approx(PAPER_FIELDS)
    for bad, word in (({**PAPER_FIELDS, "x_mm": "2"}, "x_mm must be a number"),
                      ({**PAPER_FIELDS, "yaw_deg": math.nan}, "yaw_deg must be finite"),
                      ({**PAPER_FIELDS, "z_mm": 5000.0}, "z_mm = 5000"),
                      ({k: v for k, v in PAPER_FIELDS.items() if k != "roll_deg"}, "roll_deg"),
                      ({**PAPER_FIELDS, "pitch_deg": True}, "pitch_deg must be a number")):
        with pytest.raises(InvalidInputError, match=word):
            model.pose_from_fields(bad)


def test_reachability_reports_lengths_margins_and_the_first_violated_limit(robot):
    ok = model.reachability(robot, paper_pose(robot))
    assert ok["reachable"] and ok["error"] is None
    assert len(ok["leg_lengths_mm"]) == 6 and min(ok["stroke_margin_mm"]) > 0
    assert 1 < ok["condition_number"] < ok["condition_number_max"]
    json.dumps(ok)  # JSON-ready
    far = model.reachability(robot, paper_pose(robot) + [0, 0, 0.14, 0, 0, 0])
    assert not far["reachable"] and far["error"]["type"] == "StrokeLimitError" and far["error"]["leg"] is not None
    assert min(far["stroke_margin_mm"]) < 0
    below = model.reachability(robot, robot.home_pose - [0, 0, 0.3, 0, 0, 0])
    assert below["error"]["type"] == "UnreachablePoseError"
    singular = model.reachability(robot, robot.home_pose + [0, 0, 0, 0, 0, math.pi / 2])
    assert singular["error"]["type"] == "SingularPoseError"
    json.dumps(singular)  # an infinite condition number becomes null


def test_path_margins_name_the_worst_limit(robot):
    path = checked_path(robot, robot.home_pose, paper_pose(robot))
    margins = model.path_margins(robot, path)
    assert margins["waypoints"] == len(path)
    assert margins["worst"]["limit"] in ("stroke", "universal joint", "spherical joint", "condition number")
    assert 0 < margins["worst"]["fraction"] < 1
    assert model.path_margins(robot, np.empty((0, 6))) == {"waypoints": 0}


def test_vibration_preview_matches_the_core_and_says_why_it_is_infeasible(robot):
    pose = paper_pose(robot)
    settings = {**model.stream_defaults(robot), **model.vibration_from_fields(VIBRATION)}
    preview = model.vibration_preview(robot, pose, settings)
    plan = decompose_vibration(robot, pose, acceleration_g=0.3, frequency=35.0)
    assert preview["feasible"] and preview["reason"] is None
    np.testing.assert_allclose(preview["leg_amplitudes_um"], plan.leg_amplitudes * 1e6)
    np.testing.assert_allclose(preview["gains"], plan.gains)
    assert max(preview["peak_leg_acceleration_g"]) < preview["limits"]["acceleration_max_g"]
    too_much = model.vibration_preview(robot, pose, {**settings, "acceleration_g": 3.0})
    assert not too_much["feasible"] and "VibrationLimitError" in too_much["reason"]
    assert len(too_much["leg_amplitudes_um"]) == 6  # the decomposition is shown anyway
    band = model.vibration_preview(robot, pose, {**settings, "frequency_hz": 150.0})
    assert "outside the vibration unit's band" in band["reason"]
    ranged = model.vibration_preview(robot, pose, {**settings, "acceleration_g": 11.0},
                                     {"acceleration_g": (0.0, 10.0)})
    assert "outside the planner's range" in ranged["reason"]
    zero = model.vibration_preview(robot, pose, {**settings, "direction": [0.0, 0.0, 0.0]})
    assert not zero["feasible"] and "direction" in zero["reason"]


def test_vibration_fields_map_to_planner_parameters():
    s = model.vibration_from_fields(VIBRATION)
    assert s == {"direction": [0.0, 0.0, 1.0], "frame": "platform", "amplitude_m": 0.0, "acceleration_g": 0.3,
                 "frequency_hz": 35.0, "phase_rad": 0.0, "duration_s": 3.0, "ramp_s": 0.2}
    a = model.vibration_from_fields({**VIBRATION, "mode": "amplitude", "amplitude_um": 50, "phase_deg": 180})
    assert a["amplitude_m"] == pytest.approx(50e-6) and "acceleration_g" not in a
    assert a["phase_rad"] == pytest.approx(math.pi)
    for bad in ({**VIBRATION, "direction": [0, 1]}, {**VIBRATION, "frame": "world"}, {**VIBRATION, "mode": "x"},
                {**VIBRATION, "frequency_hz": None}, [1, 2]):
        with pytest.raises(InvalidInputError):
            model.vibration_from_fields(bad)


def test_rate_limiter_decimator_and_stream_buffer():
    limiter = RateLimiter(5.0, 10.0)
    assert sum(limiter.allow(0.0) for _ in range(20)) == 10
    assert limiter.allow(0.2) and not limiter.allow(0.2)  # one token back after 0.2 s at 5/s
    dec = model.Decimator(2)
    kept = np.concatenate([dec.take(3), 3 + dec.take(4), 7 + dec.take(5)])
    np.testing.assert_array_equal(kept, np.arange(0, 12, 2))  # every other sample across batches
    buf = model.StreamBuffer(keep_s=1.0)
    for k in range(30):
        t = 0.1 * k + np.arange(50) * 0.002
        buf.add(t, np.ones((50, 3)) * k)
    t, rows = buf.arrays(3)
    assert t[-1] - t[0] < 1.2 and rows.shape == (t.size, 3)


def test_jsonable_turns_numpy_and_non_finite_numbers_into_json():
    value = model.jsonable({"a": np.arange(3), "b": np.float64(np.inf), "c": [np.nan, 1.5], "d": np.int64(2)})
    assert json.dumps(value) == '{"a": [0, 1, 2], "b": null, "c": [null, 1.5], "d": 2}'


# -- server -------------------------------------------------------------------------------------------
class FakeBackend:
    def __init__(self):
        self.commands = []

    def hello(self):
        return {"convention": model.CONVENTION}

    def command(self, cmd, args, reply):
        self.commands.append((cmd, args))
        threading.Timer(0.01, reply, [{"ok": True, "message": f"did {cmd}"}]).start()  # from another thread

    def file(self, kind, name):
        return STATIC_DIR / "style.css" if (kind, name) == ("report", "a.png") else None


@pytest.fixture
def server():
    backend = FakeBackend()
    srv = UiServer(bind("127.0.0.1", 0), "s3cret", backend, command_rate=5.0)
    srv.start()
    yield srv, backend
    srv.stop()


def fetch(url, headers=None, method="GET"):
    try:
        with urllib.request.urlopen(urllib.request.Request(url, headers=headers or {}, method=method), timeout=5) as r:
            return r.status, dict(r.headers), r.read()
    except urllib.error.HTTPError as exc:
        return exc.code, dict(exc.headers), exc.read()


def test_every_route_needs_the_token(server):
    srv, backend = server
    base = f"http://127.0.0.1:{srv.port}"
    assert srv.url == f"{base}/?token=s3cret"
    for path in ("/", "/index.html", "/static/app.js", "/files/report/a.png", "/?token=wrong"):
        status, _, body = fetch(base + path)
        assert status == 401, path
        assert b"token" in body
    status, headers, body = fetch(base + "/?token=s3cret")
    assert status == 200 and b"<canvas" in body
    assert "HttpOnly" in headers["Set-Cookie"] and "SameSite=Strict" in headers["Set-Cookie"]
    assert "default-src 'self'" in headers["Content-Security-Policy"]
    cookie = {"Cookie": "stewart_ui_token=s3cret"}
    for path in ("/static/app.js", "/static/style.css"):
        assert fetch(base + path, cookie)[0] == 200
    assert fetch(base + "/static/app.js", {"Authorization": "Bearer s3cret"})[0] == 200
    assert fetch(base + "/files/report/a.png", cookie)[0] == 200
    assert fetch(base + "/files/report/b.png", cookie)[0] == 404
    assert fetch(base + "/static/../server.py", cookie)[0] == 404
    assert fetch(base + "/static/%2e%2e%2fserver.py", cookie)[0] == 404
    assert fetch(base + "/?token=s3cret", method="POST")[0] == 405
    assert backend.commands == []


def test_websocket_needs_the_token_and_a_same_site_origin(server):
    srv, backend = server
    ws = f"ws://127.0.0.1:{srv.port}/ws"
    for url, kwargs in ((ws, {}), (ws + "?token=nope", {}),
                        (ws + "?token=s3cret", {"origin": "http://evil.example"})):
        with pytest.raises(InvalidStatus) as info:
            with connect(url, open_timeout=5, **kwargs):
                pass
        assert info.value.response.status_code == 403
    assert backend.commands == []
    with connect(ws + "?token=s3cret", open_timeout=5, origin=f"http://127.0.0.1:{srv.port}") as c:
        assert json.loads(c.recv(timeout=5))["type"] == "hello"
    with connect(ws, open_timeout=5, additional_headers={"Cookie": "stewart_ui_token=s3cret"}) as c:
        assert json.loads(c.recv(timeout=5))["type"] == "hello"


def test_commands_are_rate_limited_but_stop_and_estop_never(server):
    srv, backend = server
    with connect(f"ws://127.0.0.1:{srv.port}/ws?token=s3cret", open_timeout=5) as c:
        c.recv(timeout=5)
        for i in range(14):
            c.send(json.dumps({"id": i, "cmd": "move", "args": {}}))
        for i in range(14, 34):
            c.send(json.dumps({"id": i, "cmd": "estop" if i % 2 else "stop", "args": {}}))
        c.send(json.dumps({"id": 99, "cmd": "format_disk", "args": {}}))
        c.send("not json")
        replies = {}
        while len(replies) < 36:
            msg = json.loads(c.recv(timeout=5))
            replies[msg["id"] if msg["id"] is not None else "malformed"] = msg
    refused = [i for i in range(14) if not replies[i]["ok"]]
    assert len(refused) == 4 and all("rate limit" in replies[i]["message"] for i in refused)
    assert all(replies[i]["ok"] for i in range(14, 34))
    assert "unknown command" in replies[99]["message"] and "malformed" in replies["malformed"]["message"]
    assert [c for c, _ in backend.commands].count("move") == 10


def test_frames_reach_every_page(server):
    srv, _ = server
    with connect(f"ws://127.0.0.1:{srv.port}/ws?token=s3cret", open_timeout=5) as a, \
            connect(f"ws://127.0.0.1:{srv.port}/ws?token=s3cret", open_timeout=5) as b:
        a.recv(timeout=5), b.recv(timeout=5)
        deadline = time.monotonic() + 5
        while len(srv.clients) < 2 and time.monotonic() < deadline:
            time.sleep(0.01)
        srv.broadcast({"type": "frame", "n": 1})
        assert json.loads(a.recv(timeout=5)) == json.loads(b.recv(timeout=5)) == {"type": "frame", "n": 1}


def test_a_taken_port_is_refused_in_one_line():
    with socket.create_server(("127.0.0.1", 0)) as taken:
        port = taken.getsockname()[1]
        with pytest.raises(PortInUseError, match=f"port {port} on 127.0.0.1 is already in use"):
            bind("127.0.0.1", port)


@pytest.mark.integration
def test_the_node_exits_2_with_one_line_when_its_port_is_taken(ros_domain):
    with socket.create_server(("127.0.0.1", 0)) as taken:
        port = taken.getsockname()[1]
        proc = subprocess.run([sys.executable, "-m", "stewart_vibration.nodes.planning_ui_node", "--ros-args",
                               "-p", f"port:={port}"], env=ros_environment(ros_domain), capture_output=True,
                              text=True, timeout=60)
    assert proc.returncode == 2
    lines = [line for line in (proc.stdout + proc.stderr).splitlines() if line.strip()]
    assert len(lines) == 1 and f"port {port} on 127.0.0.1 is already in use" in lines[0], lines
