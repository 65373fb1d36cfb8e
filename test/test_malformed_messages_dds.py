"""No message can kill a node, over real DDS.

The whole suite runs as separate processes -- hardware emulator, kinematics, vibration planner, leg-force
estimator, MCAP recorder, planning UI (a page open on it, so it reads its 500 Hz streams too), Foxglove bridge
(a client watching its scene, so it reads the ground-truth pose) -- beside the runner's own client
(nodes.suite_client.SuiteClient) in this process. Before any node starts, a malformed vibration/status and
kinematics/guard_status are latched on their transient-local topics. Then a seeded fuzzer publishes malformed
versions of every message type each node subscribes to (tests/malformed_messages.py: /diagnostics statuses named
like each publisher's with non-numeric values, vibration and guard statuses with values outside their tables and
ranges, NUL and non-UTF-8 strings, joint states, poses, wrenches and trajectories
with NaN / inf / huge values, wrong lengths and names, garbage CDR, /clock with negative seconds) and sends the
malformed target poses as kinematics' move_to_pose goals, and the test checks that every node is alive, still
does its job (clock, pose and force estimates, a planned path, service answers, frames to the page and the
scene), counted what it ignored on /diagnostics and refused every bad goal with its outcome code; restarted
nodes get the latched malformed status again and survive it.

Also, as the issue's user saw it: a spoofed emulator status with a non-numeric rejection count during a move
(kinematics stays alive and the move completes), and a burst of 200 e-stops from the planning UI (every one
answered within 5 s).
"""

from __future__ import annotations

import asyncio
import json
import re
import threading
import time

import malformed_messages as bad
import numpy as np
import pytest
import websockets
from action_msgs.srv import CancelGoal
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, WrenchStamped
from rcl_interfaces.msg import Log
from rclpy._rclpy_pybind11 import RCLError
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from ros_client import RosTestClient
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory
from websockets.sync.client import connect

from stewart_vibration import load_robot
from stewart_vibration.errors import InvalidInputError, MalformedMessageError, StewartError
from stewart_vibration.kinematics import check_pose
from stewart_vibration.messages.diagnostic_status import decode_diagnostic_array
from stewart_vibration.messages.fields import check_frame
from stewart_vibration.nodes.message_conversions import pose_from_msg, pose_stamped
from stewart_vibration.nodes.move_messages import MOVE_ACTION
from stewart_vibration.nodes.suite_client import SuiteClient
from stewart_vibration.paper import paper_pose
from stewart_vibration.robot import LEG_NAMES, VIB_NAMES
from stewart_vibration.runtime.processes import ros_environment, start_python_module
from stewart_vibration_interfaces.action import MoveToPose
from stewart_vibration_interfaces.msg import ForceGuardStatus, LegTrajectoryStatus, Outcome, VibrationUnitsStatus
from stewart_vibration_interfaces.srv import PlanPath

pytestmark = [pytest.mark.integration]
SIM = ["--ros-args", "-p", "use_sim_time:=true"]
STATUS_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
FOXGLOVE_SUBPROTOCOL = "foxglove.sdk.v1"


def nodes(tmp_path) -> dict:
    """name: (module, arguments) of the whole suite with the UI and the Foxglove bridge (any free ports)."""
    return {
        "emulator": ("stewart_vibration.nodes.hardware_emulator_node", SIM + ["-p", "real_time_factor:=1"]),
        "kinematics": ("stewart_vibration.nodes.kinematics_node", SIM),
        "planner": ("stewart_vibration.nodes.vibration_planner_node", SIM),
        "estimator": ("stewart_vibration.nodes.leg_force_estimator_node", SIM),
        "recorder": ("stewart_vibration.nodes.mcap_recorder_node", SIM + ["-p", f"output_dir:={tmp_path / 'bag'}"]),
        "ui": ("stewart_vibration.nodes.planning_ui_node", SIM + ["-p", "port:=0"]),
        "foxglove": ("stewart_vibration.nodes.foxglove_bridge_node", SIM + ["-p", "port:=0"]),
    }


CONTROLLER_NODES = {"kinematics", "vibration_planner", "leg_force_estimator", "planning_ui"}  # no ground truth
# what each node must have counted as malformed, per input, after the fuzz (its /diagnostics status name)
EXPECTED = {
    "hardware_emulator: hardware emulator": ["/clock"],
    # (kinematics reads the emulator's answers on legs/trajectory_status now, not on /diagnostics: typed, nothing
    # to count, it must only survive them)
    "kinematics: kinematics": ["legs/joint_states", "platform/external_wrench_estimate", "/clock"],
    "vibration_planner: vibration planner": ["vibration/status", "/clock"],
    "leg_force_estimator: leg force estimator": ["legs/joint_states", "vibration/status", "legs/joint_trajectory",
                                                 "vibration/joint_trajectory", "/clock"],
    "planning_ui: planning UI": ["vibration/status", "/diagnostics", "legs/joint_states",
                                 "platform/pose_estimate", "legs/force_estimate", "/clock"],
    "foxglove_bridge: foxglove bridge": ["vibration/status", "vibration/joint_trajectory", "ground_truth/platform_pose",
                                         "/clock"],
}


class Suite:
    """The node processes, a recording client and the fuzzer's publishers (raw: bytes as they are)."""

    def __init__(self, domain: int, tmp_path):
        self.domain, self.tmp_path = domain, tmp_path
        self.client = c = RosTestClient("fuzz_client")
        self.status_pub = c.node.create_publisher(VibrationUnitsStatus, "vibration/status", STATUS_QOS)
        self.guard_pub = c.node.create_publisher(ForceGuardStatus, "kinematics/guard_status", STATUS_QOS)
        self.procs: dict = {}
        self.diagnostics: dict[str, dict] = {}  # status name -> (wall time, values) of its latest
        c.node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diagnostics, 200)
        self.clock = c.subscribe("/clock", Clock, depth=10)
        self.estimates = c.subscribe("platform/pose_estimate", PoseStamped, depth=10)
        self.forces = c.subscribe("legs/force_estimate", JointState, depth=10)
        self.truth = c.subscribe("ground_truth/platform_pose", PoseStamped, depth=100)

    def _on_diagnostics(self, msg) -> None:
        for status in msg.status:
            self.diagnostics[status.name] = (time.monotonic(), {kv.key: kv.value for kv in status.values})

    def start(self, names) -> None:
        env = ros_environment(self.domain)
        self.procs.update({name: start_python_module(name, module, args, env, self.tmp_path / "logs")
                           for name, (module, args) in nodes(self.tmp_path).items() if name in names})

    def dead(self) -> list[str]:
        return [name for name, proc in self.procs.items() if not proc.alive()]

    def logs(self) -> str:
        return "\n".join(f"--- {n}\n{p.log_text()[-2500:]}" for n, p in self.procs.items())

    def malformed(self, name: str, input_name: str) -> int:
        values = self.diagnostics.get(name, (0.0, {}))[1]
        return int(values.get(f"malformed {input_name}", "0"))

    def published_since(self, name: str, since: float) -> bool:
        return self.diagnostics.get(name, (0.0, {}))[0] > since

    def close(self) -> None:
        self.client.close()
        for proc in self.procs.values():
            proc.stop()


@pytest.fixture
def suite(ros_domain, tmp_path):
    s = Suite(ros_domain, tmp_path)
    try:
        yield s
    finally:
        s.close()


class Page:
    """A planning-UI page (its WebSocket, with the token from the node's log) receiving frames in a thread."""

    def __init__(self, log_text):
        found = re.search(r"planning UI at http://([\d.]+:\d+)/\?token=(\S+)", log_text)
        assert found, log_text[-2000:]
        url = f"ws://{found.group(1)}/ws?token={found.group(2)}"
        self.ws = connect(url, open_timeout=10, max_size=None).__enter__()  # closed by close()
        self.frames, self.replies, self._stop = 0, {}, threading.Event()
        self.thread = threading.Thread(target=self._receive, daemon=True)
        self.thread.start()

    def _receive(self) -> None:
        while not self._stop.is_set():
            try:
                msg = json.loads(self.ws.recv(timeout=0.5))
            except TimeoutError:
                continue
            except Exception:  # noqa: BLE001 - closed
                return
            if msg.get("type") == "frame":
                self.frames += 1
            elif msg.get("type") == "reply":
                self.replies[msg.get("id")] = (time.monotonic(), msg)

    def send(self, ident: int, cmd: str, args=None) -> None:
        self.ws.send(json.dumps({"id": ident, "cmd": cmd, "args": args or {}}))

    def close(self) -> None:
        self._stop.set()
        self.ws.close()
        self.thread.join(5)


class SceneWatcher:
    """A Foxglove client subscribed to the bridge's scene channels (so the bridge reads ground_truth/platform_pose)."""

    def __init__(self, port: int, namespace: str = ""):
        self.port, self.messages, self._stop = port, 0, threading.Event()
        self.scene = {f"{namespace}/scene/transforms", f"{namespace}/scene/entities"}
        self.thread = threading.Thread(target=lambda: asyncio.run(self._run()), daemon=True)
        self.thread.start()

    async def _run(self) -> None:
        async with websockets.connect(f"ws://127.0.0.1:{self.port}", subprotocols=[FOXGLOVE_SUBPROTOCOL],
                                      max_size=None) as ws:
            channels: dict = {}
            while not self._stop.is_set():
                try:
                    msg = await asyncio.wait_for(ws.recv(), 0.5)
                except TimeoutError:
                    continue
                if isinstance(msg, str) and json.loads(msg).get("op") == "advertise":
                    channels.update({c["topic"]: c["id"] for c in json.loads(msg)["channels"]})
                    wanted = [t for t in self.scene if t in channels]
                    await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                        {"id": i, "channelId": channels[t]} for i, t in enumerate(wanted, start=1)]}))
                elif isinstance(msg, bytes):
                    self.messages += 1

    def close(self) -> None:
        self._stop.set()
        self.thread.join(5)


def trajectory_statuses(rng, count: int = 30) -> list[bytes]:
    """legs/trajectory_status answers (the emulator's, to leg trajectories) that answer nothing kinematics sent or
    are malformed: refusals and takes of unknown, NaN or inf final lengths, codes outside the outcome table, NaN /
    inf end times, empty, replacement-character and 70 kB messages, and mangled bytes."""
    out = []
    refused = LegTrajectoryStatus(seq=7, accepted=False, points=3, end_time_s=float("nan"))
    refused.final_positions = [float("nan")] * 6
    refused.outcome.code, refused.outcome.message = 9999, "refused"
    for i in range(count):
        if i % 4 == 3:
            out.extend(bad.mangled(rng, serialize_message(refused), 1, i))
            continue
        msg = LegTrajectoryStatus(seq=int(rng.integers(0, 2**32)), accepted=bool(i % 2),
                                  points=int(rng.integers(0, 2**32)),
                                  end_time_s=float(rng.choice([np.nan, np.inf, -np.inf, 1e300])))
        msg.final_positions = [float(v) for v in rng.choice([np.nan, np.inf, 0.3, -1.0], 6)]
        msg.outcome.code = int(rng.choice([0, 302, 9999, 65535]))
        msg.outcome.message = ["", "\ufffd" * 10, "x" * 70_000][i % 3]
        out.append(serialize_message(msg))
    return out


def goal_refusal(robot, target: PoseStamped) -> str | None:
    """The outcome a move goal to ``target`` (node defaults otherwise) must be refused with -- the node checks the
    frame, the pose message, then the pose -- or None for a legal one."""
    try:
        check_frame(target.header.frame_id, "target pose")
    except MalformedMessageError:
        return "UNKNOWN_FRAME"
    try:
        check_pose(robot, pose_from_msg(target.pose))
    except StewartError as exc:
        return exc.outcome
    return None


def goal_targets(data: list[bytes]) -> list[PoseStamped]:
    """The malformed PoseStamped of ``data`` that are messages at all (mangled bytes that do not deserialize
    cannot be a goal's target: the action's own transport refuses them before the node sees them)."""
    out = []
    for raw in data:
        try:
            out.append(deserialize_message(raw, PoseStamped))
        except Exception:  # noqa: BLE001 - rclpy raises its RMW error types
            continue
    return out


def subscribed(client: RosTestClient, topic: str, node: str) -> bool:
    return any(i.node_name == node for i in client.node.get_subscriptions_info_by_topic(topic))


def test_fuzzed_messages_kill_no_node_and_are_counted(suite, robot):
    rng = np.random.default_rng(23)
    c = suite.client
    # latched before any node starts: every subscriber of these transient-local topics gets them on start
    latched_status = bad.vibration_statuses(rng, 6)[0]  # a field outside its range
    suite.status_pub.publish(latched_status)
    suite.guard_pub.publish(bad.guard_statuses(rng)[0])
    suite.start([name for name in nodes(suite.tmp_path) if name != "emulator"])  # the emulator's own status later
    runner = SuiteClient("/", suite.domain, 1.0, suite.dead, suite.tmp_path / "logs")  # the runner's client
    page = watcher = None
    try:
        def spin(seconds: float) -> None:
            deadline = time.monotonic() + seconds
            while time.monotonic() < deadline:
                c.spin_for(0.003)
                for _ in range(20):
                    runner.spin_once(0.0)

        def spin_until(predicate, timeout: float) -> bool:
            deadline = time.monotonic() + timeout
            while time.monotonic() < deadline and not predicate():
                spin(0.02)
            return bool(predicate())

        latched_readers = ("vibration_planner: vibration planner", "leg_force_estimator: leg force estimator",
                           "planning_ui: planning UI", "foxglove_bridge: foxglove bridge")
        assert spin_until(lambda: all(suite.malformed(n, "vibration/status") >= 1 for n in latched_readers) and
                          runner.malformed.counter.counts.get("vibration/status", 0) >= 1 and
                          runner.malformed.counter.counts.get("kinematics/guard_status", 0) >= 1, 60), \
            ("latched", {n: suite.malformed(n, "vibration/status") for n in latched_readers},
             runner.malformed.counter.counts, suite.logs())
        suite.start(["emulator"])
        assert spin_until(lambda: suite.clock and len(suite.estimates) > 10 and len(suite.forces) > 10, 90), \
            suite.logs()
        for sub in runner.readiness_subs:  # as the runner does once the suite is ready (500 Hz it need not read)
            runner.node.destroy_subscription(sub)
        runner.readiness_subs = []

        page = Page(suite.procs["ui"].log_text())
        port = re.search(r"Foxglove WebSocket server at ws://[\d.]+:(\d+)", suite.procs["foxglove"].log_text())
        assert port, suite.logs()
        watcher = SceneWatcher(int(port.group(1)))
        assert spin_until(lambda: subscribed(c, "/legs/force_estimate", "planning_ui") and
                          subscribed(c, "/ground_truth/platform_pose", "foxglove_bridge") and page.frames > 0,
                          30), suite.logs()
        # the rule of the emulator, over DDS: with every node up and a page open (the UI's streams subscribed),
        # only viewers and judges read the truth; the bridge does (the query sees such readers)
        truth_readers = {name for name, ns in c.node.get_node_names_and_namespaces()
                         for topic, _ in c.node.get_subscriber_names_and_types_by_node(name, ns)
                         if "/ground_truth/" in topic}
        assert "foxglove_bridge" in truth_readers and not truth_readers & CONTROLLER_NODES, truth_readers

        raw = {topic: c.node.create_publisher(kind, topic, 50) for topic, kind in (
            ("legs/joint_states", JointState), ("legs/force_estimate", JointState),
            ("ground_truth/platform_pose", PoseStamped),
            ("platform/pose_estimate", PoseStamped), ("platform/external_wrench_estimate", WrenchStamped),
            ("legs/joint_trajectory", JointTrajectory),
            ("vibration/joint_trajectory", JointTrajectory), ("/diagnostics", DiagnosticArray),
            ("/clock", Clock), ("legs/trajectory_status", LegTrajectoryStatus))}
        raw["/rosout"] = c.node.create_publisher(Log, "/rosout", QoSProfile(
            depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        raw["vibration/status"], raw["kinematics/guard_status"] = suite.status_pub, suite.guard_pub
        batches = {
            "legs/joint_states": bad.joint_states(rng), "legs/force_estimate": bad.joint_states(rng, LEG_NAMES, 30),
            "ground_truth/platform_pose": bad.poses(rng), "platform/pose_estimate": bad.poses(rng, 30)}
        # malformed target poses: kinematics' move goals now (drawn here: the seeded fuzz of the rest is the same)
        targets = goal_targets(bad.poses(rng))
        batches |= {
            "platform/external_wrench_estimate": bad.wrenches(rng),
            "legs/joint_trajectory": bad.trajectories(rng, LEG_NAMES),
            "vibration/joint_trajectory": bad.trajectories(rng, VIB_NAMES), "/diagnostics": bad.diagnostic_arrays(rng),
            "vibration/status": bad.vibration_statuses(rng), "kinematics/guard_status": bad.guard_statuses(rng),
            "/clock": [serialize_message(Clock(clock=Time(sec=int(s), nanosec=0))) for s in (-1, -5, -2**31)]
            + bad.mangled(rng, serialize_message(Clock()), 6),
            "/rosout": [serialize_message(Log(name="mcap_recorder", msg=f"recording to {path}"))
                        for path in ("/tmp/" + "a" * 5000, "/tmp/run\x01/x.mcap", "/tmp/\ufffd.mcap")],
            # its own generator: the seeded fuzz of the others stays the same
            "legs/trajectory_status": trajectory_statuses(np.random.default_rng(29)),
        }
        for topic in batches:
            assert spin_until(lambda t=topic: raw[t].get_subscription_count() > 0, 30), (topic, suite.logs())
        assert c.action_server_ready(MoveToPose, MOVE_ACTION, 30), suite.logs()
        moves = []  # (target, ActionGoal) of every move goal sent
        plan = PlanPath.Request(waypoints=[pose_stamped(robot.home_pose, Time(), "base")])
        plan.waypoints[0].pose.position.x = float("nan")
        sent, unsendable = 0, []
        for i in range(max(map(len, batches.values()))):
            if i < len(targets):
                moves.append((targets[i], c.send_goal(MOVE_ACTION, MoveToPose.Goal(target=targets[i]))))
                sent += 1
            for topic, messages in batches.items():
                if i < len(messages):
                    try:
                        raw[topic].publish(messages[i])
                        sent += 1
                    except RCLError:  # Fast DDS deserializes a small fixed-size type (Clock) to send it: refused
                        unsendable.append(topic)
            if i % 10 == 0:  # a malformed request: refused with its code, no crash
                assert c.call(PlanPath, "kinematics/plan_path", plan).outcome.code == Outcome.INVALID_ARGUMENT
            spin(0.01)
        # kinematics reads only the newest wrench estimate of a batch between moves, the bridge the newest
        # ground-truth pose at each scene tick, and rclpy's /clock subscription keeps one message (the emulator's
        # next one, 10 ms later, may replace a bad one before it is taken): denser streams meet those readers
        negative = serialize_message(Clock(clock=Time(sec=-3, nanosec=0)))
        for i in range(400):
            for topic in ("ground_truth/platform_pose", "platform/external_wrench_estimate"):
                raw[topic].publish(batches[topic][i % len(batches[topic])])
            raw["/clock"].publish(negative)
            sent += 3
            spin(0.001)
        assert sent > 1000 and set(unsendable) <= {"/clock"}, unsendable
        spin(1.0)
        assert not suite.dead(), ("dead after the fuzz", suite.dead(), suite.logs())
        # every bad goal was refused with its code (or BUSY: checked first, while another goal runs), nothing run;
        # the legal ones among them (a frame "base\0x" reads "base", the stamp is not used) are moves of nothing,
        # judged on the states kinematics reads -- fuzzed ones among them (stamped far ahead, lengths of another
        # pose): such a goal may end TIMEOUT, the robot holding
        ended = []
        for target, goal in moves:
            name, message = goal.outcome(30)
            expected = goal_refusal(robot, target)
            ended.append((expected, name))
            assert message, (target, name)
            if expected is None:
                assert name in ("SUCCEEDED", "BUSY", "TIMEOUT"), (target, name, message)
            else:
                assert name in (expected, "BUSY") and goal.status() == 6, (target, expected, name, message)
        assert len(moves) > 20 and sum(expected is not None for expected, _ in ended) > len(moves) // 2, ended

        # every node counted what it ignored, per input, on /diagnostics (the runner: in its client)
        def counted() -> list[str]:
            return [f"{name}: {i}" for name, inputs in EXPECTED.items() for i in inputs if suite.malformed(name, i) < 1]

        assert spin_until(lambda: not counted(), 30), ("not counted", counted(), suite.logs())
        for topic in ("vibration/status", "/diagnostics", "kinematics/guard_status"):
            assert runner.malformed.counter.counts.get(topic, 0) >= 1, runner.malformed.counter.counts
        assert runner.vibration_status is not None and runner.vibration_status.state == "idle"  # the emulator's

        # ... and every node still works
        after = time.monotonic()
        clock, estimates, forces = len(suite.clock), len(suite.estimates), len(suite.forces)
        frames, scene = page.frames, watcher.messages
        def progress() -> dict:
            return {"clock": len(suite.clock) - clock, "estimates": len(suite.estimates) - estimates,
                    "forces": len(suite.forces) - forces, "frames": page.frames - frames,
                    "scene": watcher.messages - scene}

        assert spin_until(lambda: min(progress().values()) > 5 and progress()["estimates"] > 50 and
                          progress()["forces"] > 50, 30), ("still working?", progress(), suite.logs())
        quiet = [n for n in list(EXPECTED) + ["mcap_recorder: mcap recorder"]]
        assert spin_until(lambda: all(suite.published_since(n, after) for n in quiet), 10), \
            ("no /diagnostics since the fuzz", [n for n in quiet if not suite.published_since(n, after)])
        legal = c.plan_path(paper_pose(robot))
        assert legal.outcome.code == Outcome.SUCCEEDED and legal.path.poses, (legal.outcome, suite.logs())
        assert c.call(CancelGoal, "vibration_planner/vibrate/_action/cancel_goal", CancelGoal.Request()).return_code \
            in (CancelGoal.Response.ERROR_NONE, CancelGoal.Response.ERROR_REJECTED)  # answered (no goal to cancel)
        assert "no emergency stop" in c.call(Trigger, "hardware_emulator/reset", Trigger.Request()).message

        # restarted, the planner and the estimator get the latched malformed status again, count it and answer
        # (the emulator stopped first: a reader keeps one status on this topic, the emulator's could replace it)
        suite.procs.pop("emulator").stop()
        suite.status_pub.publish(latched_status)
        for name in ("planner", "estimator"):
            suite.procs[name].stop()
            suite.procs[name] = suite.procs[name].restart()
        restarted = time.monotonic()
        assert spin_until(lambda: all(
            suite.published_since(n, restarted) and suite.malformed(n, "vibration/status") >= 1 for n in (
                "vibration_planner: vibration planner", "leg_force_estimator: leg force estimator")), 60), \
            ("restarted", {n: suite.malformed(n, "vibration/status") for n in latched_readers[:2]}, suite.logs())
        assert c.call(CancelGoal, "vibration_planner/vibrate/_action/cancel_goal", CancelGoal.Request()).return_code \
            in (CancelGoal.Response.ERROR_NONE, CancelGoal.Response.ERROR_REJECTED)  # answered (no goal to cancel)
        assert not suite.dead(), f"dead at the end: {suite.dead()}\n{suite.logs()}"
    finally:
        for view in (page, watcher):
            if view is not None:
                view.close()
        runner.close()


def test_a_spoofed_emulator_status_during_a_move_leaves_kinematics_guarding_it(ros_domain, tmp_path):
    """Spoofed emulator answers during a move: a /diagnostics status named like the emulator's with a non-numeric
    rejection count (it killed kinematics when kinematics read the emulator's rejections there: the force guard
    was gone for that move) and legs/trajectory_status answers to no trajectory kinematics sent, odd or mangled
    (the emulator's answers now): kinematics survives them, the move goal succeeds at its target and the guard
    guards it all along (the goal's feedback never says OFF, and no load trips it; on a loaded machine it may
    stop the move for late wrench estimates, its blind-estimate watchdog, and resume it)."""
    env = ros_environment(ros_domain)
    procs = {name: start_python_module(name, module, args, env, tmp_path)
             for name, (module, args) in nodes(tmp_path).items() if name in ("emulator", "kinematics", "estimator")}
    client = RosTestClient("spoof_client")
    robot = load_robot()
    try:
        truth = client.subscribe("ground_truth/platform_pose", PoseStamped, depth=100)
        estimates = client.subscribe("platform/external_wrench_estimate", WrenchStamped, depth=10)
        diagnostics = client.subscribe("/diagnostics", DiagnosticArray, depth=200)
        guard: list = []  # every guard status, the latched one first (kinematics publishes on change)
        client.node.create_subscription(ForceGuardStatus, "kinematics/guard_status", guard.append, QoSProfile(
            depth=100, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        spoofer = client.node.create_publisher(DiagnosticArray, "/diagnostics", 50)
        answers = client.publisher("legs/trajectory_status", LegTrajectoryStatus, 50)
        assert client.spin_until(lambda: len(truth) > 50 and len(estimates) > 50, 90), procs
        assert client.wait_for_subscribers("legs/trajectory_status"), procs
        target = robot.home_pose + np.array([0.0, 0.0, 0.008, 0.0, 0.0, 0.0])  # a 1.6 s move at 5 mm/s
        move = client.move(target)
        spoofs = bad.diagnostic_arrays(np.random.default_rng(5), 21)[::7]  # the emulator's: rejections non-numeric
        odd_answers = trajectory_statuses(np.random.default_rng(6), 8)

        def kinematics_values() -> dict:
            out = {}
            for a in diagnostics:
                for s in a.status:
                    if s.name.startswith("kinematics:"):
                        out = {kv.key: kv.value for kv in s.values} | {"message": s.message}
            return out

        def at_target() -> bool:
            p = truth[-1].pose.position
            return float(np.abs(np.array([p.x, p.y, p.z]) - target[:3]).max()) < 10e-6

        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not at_target():
            for data in spoofs:
                spoofer.publish(data)
            for data in odd_answers:
                answers.publish(data)
            client.spin_for(0.02)
        assert at_target(), ([procs[n].log_text()[-2000:] for n in procs])
        assert procs["kinematics"].alive(), procs["kinematics"].log_text()
        name, message = move.outcome(30)
        assert (name, move.status()) == ("SUCCEEDED", 4), (name, message, procs["kinematics"].log_text()[-2000:])
        states = {f.feedback.guard_state for f in move.feedback}
        assert move.feedback and ForceGuardStatus.ARMED in states and ForceGuardStatus.OFF not in states, states
        load_trips = [g.message for g in guard if g.state == ForceGuardStatus.TRIPPED and
                      g.trip_limit != ForceGuardStatus.LIMIT_ESTIMATES]
        assert guard and not load_trips, load_trips
        client.spin_for(1.0)
        assert procs["kinematics"].alive(), procs["kinematics"].log_text()
        assert kinematics_values(), "kinematics' /diagnostics went silent"
    finally:
        client.close()
        for proc in procs.values():
            proc.stop()


def test_a_burst_of_200_emergency_stops_from_the_ui_is_answered_within_5_s(ros_domain, tmp_path):
    """200 e-stops from a page as fast as it can send them (15 of 200 were answered within 5 s: each was a service
    call of its own, behind the others): coalesced into few calls, every one answered, within 5 s, and the
    emulator latched its e-stop."""
    env = ros_environment(ros_domain)
    procs = {name: start_python_module(name, module, args, env, tmp_path)
             for name, (module, args) in nodes(tmp_path).items() if name in ("emulator", "ui")}
    client = RosTestClient("estop_client")
    page = None
    try:
        status = client.subscribe("vibration/status", VibrationUnitsStatus, depth=50)
        assert client.spin_until(lambda: "planning UI at" in procs["ui"].log_text() and status, 90), \
            [p.log_text()[-2000:] for p in procs.values()]
        assert client.node.create_client(Trigger, "hardware_emulator/emergency_stop").wait_for_service(
            timeout_sec=30)
        page = Page(procs["ui"].log_text())
        assert client.spin_until(lambda: page.frames > 0, 20)
        sent = time.monotonic()
        for i in range(200):
            page.send(i, "estop")
        assert client.spin_until(lambda: len(page.replies) >= 200, 5.0), (len(page.replies), procs["ui"].log_text())
        answered = sorted(t - sent for t, _ in page.replies.values())
        assert all(reply["ok"] for _, reply in page.replies.values()), list(page.replies.values())[:3]
        assert answered[-1] <= 5.0
        calls = procs["emulator"].log_text().count("emergency stop: vibration ramping to zero")
        assert 1 <= calls <= 20, calls  # coalesced: one call at a time, the rest sharing it or the next
        assert client.spin_until(lambda: status[-1].state == VibrationUnitsStatus.ESTOPPED, 5)
        print(f"200 e-stops answered after {answered[0]:.3f} .. {answered[-1]:.3f} s with {calls} calls")
    finally:
        if page is not None:
            page.close()
        client.close()
        for proc in procs.values():
            proc.stop()


def wire_clean(data: bytes, decode) -> bool:
    """Whether ``data`` decodes as its type (UTF-8 strings, right lengths) and is under 60 kB: ``decode`` is a
    messages.cdr decoder or a message class (rclpy's deserializer)."""
    try:
        if isinstance(decode, type):
            deserialize_message(data, decode)
        else:
            decode(data)
    except InvalidInputError:
        return False
    except Exception:  # rclpy's deserializer: not this type on the wire, or a string that is not UTF-8
        return False
    return len(data) < 60_000


@pytest.mark.slow
def test_the_main_job_survives_spoofed_statuses_and_prints_its_summary(ros_domain, tmp_path):
    """`stewart-vibration run` while a spoofer publishes, all along the run, a vibration/status with fields outside
    their ranges (latched: every node that starts gets it), a malformed guard status and
    /diagnostics statuses named like each node's with non-numeric counts (it ended in a traceback, no summary,
    exit 1): the run completes within its bounds (exit 0), prints its summary, and the summary lists the
    recorded statuses it could not read."""
    import os
    import signal
    import subprocess
    import sys

    out = tmp_path / "run"
    rng = np.random.default_rng(31)
    # statuses of the right type whose fields are out of range, as a spoofer sends them: well-formed
    # CDR with UTF-8 strings under 64 kB (garbage bytes and non-UTF-8 strings are recorded as they come and are
    # the MCAP reader's business; 100 kB messages at 5 Hz slow the whole suite through Fast DDS's fragmentation)
    statuses = [m for m in bad.vibration_statuses(rng, 60) if wire_clean(m, VibrationUnitsStatus)]
    guards = [m for m in bad.guard_statuses(rng) if wire_clean(m, ForceGuardStatus)]
    arrays = [m for m in bad.diagnostic_arrays(rng, 28) if wire_clean(m, decode_diagnostic_array)]
    client = RosTestClient("run_spoofer")
    status_pub = client.node.create_publisher(VibrationUnitsStatus, "/stewart/vibration/status", STATUS_QOS)
    guard_pub = client.node.create_publisher(ForceGuardStatus, "/stewart/kinematics/guard_status", STATUS_QOS)
    diag_pub = client.node.create_publisher(DiagnosticArray, "/diagnostics", 50)
    stop = threading.Event()

    def spoof() -> None:
        i = 0
        while not stop.is_set():
            status_pub.publish(statuses[i % len(statuses)])
            guard_pub.publish(guards[i % len(guards)])
            diag_pub.publish(arrays[i % len(arrays)])
            client.spin_for(0.2)
            i += 1

    log_path = tmp_path / "run.log"
    with log_path.open("w") as log:
        proc = subprocess.Popen(
            [sys.executable, "-m", "stewart_vibration", "run", "--out", str(out), "--domain-id", str(ros_domain),
             "--duration", "1.6", "--lockstep", "--json"], stdout=log, stderr=subprocess.STDOUT, text=True,
            env=dict(os.environ, PYTHONUNBUFFERED="1"), start_new_session=True)
    spoofer = threading.Thread(target=spoof, daemon=True)
    spoofer.start()
    try:
        finished = proc.wait(timeout=400) is not None
    except subprocess.TimeoutExpired:
        finished = False
    finally:
        stop.set()
        spoofer.join(5)
        client.close()
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    stdout = log_path.read_text()
    assert finished, stdout[-4000:]
    assert "Traceback" not in stdout, stdout[-4000:]
    assert proc.returncode == 0, stdout[-4000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["failure"] is None and not summary["bound_failures"] and len(summary["vibrations"]) == 1
    assert summary["streams"]["malformed_statuses"], summary["streams"]
    assert "ignored malformed vibration/status" in stdout, stdout[-4000:]  # the runner's client said so
