"""planning_ui node: the surgical planning UI, a browser page over the suite's own interfaces.

Serves the page (stewart_vibration/ui/static) and a WebSocket on ``host``:``port`` (127.0.0.1:8080 by
default; port 0 = any free port) behind a random access token, and logs its URL with the token
(``planning UI at http://127.0.0.1:8080/?token=...``). A taken port: one line, exit code 2.

It uses what any client of the suite uses, nothing private:
the kinematics/move_to_pose action (a move is a goal: its feedback and result, with the outcome code, say how
it went; nothing is read from text); calls kinematics/plan_path (PlanPath: a refusal's code and reason are in
the answer), vibration_planner/get_parameters and
describe_parameters (the streaming settings), the vibration_planner/vibrate action (a start is a goal, its
refusal the result's outcome; stop cancels every vibrate goal), hardware_emulator/emergency_stop and /reset
(Trigger); subscribes the vibrate action's feedback (any client's vibration: its plan and what the sensors
show delivered), legs/joint_states, platform/pose_estimate (the controller's pose, FK of the
sensed lengths: the page shows what the controller knows, never the emulator's truth),
legs/force_estimate (raw, best effort: a slow page never holds up a publisher), vibration/status,
/diagnostics (the recorder's status names the file it writes in its ``path`` value).

Commands from the page are checked here with the core's own checks before anything is sent (a move with
``kinematics.check_pose``, a start with the planner's settings check and the decomposition's limits) and
rate-limited; stop and the emergency stop are never limited or delayed. Live data go to the page at
``frame_rate_hz`` with the 500 Hz streams decimated to ``plot_rate_hz``; those subscriptions exist only while a
page is open (or a move or vibration it started is followed), so an unwatched UI costs the suite nothing.
After a vibration the page gets its run summary (amplitude, direction error, phases, force error), computed
from the full-rate streams.

The web server runs in a thread of its own (stewart_vibration.ui.server); every rclpy call is made here,
in the executor's thread: commands are queued and run from a 100 Hz steady timer while a page is open (the
EventsExecutor has no guard conditions).
"""

from __future__ import annotations

import collections
import math
import secrets
import threading
import time
from pathlib import Path

import numpy as np
from action_msgs.srv import CancelGoal
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.srv import DescribeParameters, GetParameters
from rclpy.action import ActionClient
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.parameter import parameter_value_to_python
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

from stewart_vibration_interfaces.action import MoveToPose, Vibrate
from stewart_vibration_interfaces.msg import VibrationUnitsStatus
from stewart_vibration_interfaces.srv import PlanPath

from ..errors import MalformedMessageError, StewartError
from ..kinematics.robot_config import load_robot
from ..messages.joint_states import JointStateDecoder, decode_joint_states_dropping_malformed
from ..messages.stamped import poses_from_cdr
from ..messages.status_values import (
    planner_settings,
    recorder_files,
    statuses_from_cdr,
    vibration_report_from_cdr,
)
from ..paper import paper_pose
from ..parameters.tables import PLANNING_UI
from ..robot import STANDARD_GRAVITY
from ..ui import model
from ..ui.server import UiServer, bind
from ..vibration.settings import STREAM_KEYS, VIBRATION_KEYS, default_settings
from .diagnostics import OK, Diagnostics, MalformedInputs
from .message_conversions import JointColumns, pose_from_msg, pose_stamped
from .move_messages import MOVE_ACTION, move_goal, move_result_record
from .node_parameters import declare_table
from .outcomes import outcome_name
from .run_loop import STATUS_QOS, run_node
from .service_calls import GoalAcceptances, send_goal_recovering_async
from .vibration_goal import goal_message, plan_record, settings_of_plan

STREAM_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT)
SETTLE_POSITION_M = 1e-5  # a move is settled when the pose estimate holds within 10 um / 0.01 deg for 0.5 s
SETTLE_ANGLE_RAD = math.radians(0.01)
SETTLE_HOLD_S = 0.5
MOVE_TIMEOUT_S = 120.0  # a move not settled by then no longer blocks a start
CALL_TIMEOUT_S = 10.0
COMMAND_POLL_S = 0.01  # the page's commands are run in the executor's thread within this time
LEVELS = {0: "OK", 1: "WARN", 2: "ERROR", 3: "STALE"}
EVENTS_KEPT = 30
STREAMS_IDLE_S = 5.0  # the 500 Hz subscriptions are dropped this long after the last page closed
RUNNING_STATES = ("pending", "ramping_in", "running", "ramping_out")
MAX_NODE_STATUSES = 256  # distinct /diagnostics status names kept for the page (a spoofer could send millions)
ESTOP_RESEND_S = 1.0  # an unanswered e-stop call is sent again after this (its answer may be lost; it is idempotent)


class PlanningUiNode(Node):
    """Backend of stewart_vibration.ui.server: hello(), command(), file()."""

    def __init__(self):
        super().__init__("planning_ui")
        params = declare_table(self, PLANNING_UI)
        host, port = params["host"], params["port"]
        self.frame_rate, self.plot_rate = params["frame_rate_hz"], params["plot_rate_hz"]
        self.stale_after, command_rate = params["stale_after_s"], params["command_rate_hz"]
        keep = params["summary_buffer_s"]
        self.robot = load_robot(self.get_parameter("robot_config").value or None)
        if host not in ("127.0.0.1", "::1", "localhost"):
            self.get_logger().warning(f"serving on {host}: the page (and the robot) can be reached from other "
                                      "machines by anyone who has the token")
        self.token = secrets.token_urlsafe(24)
        sock = bind(host, int(port))  # PortInUseError: one line, exit code 2 (run_node)

        self.diagnostics = Diagnostics(self, "planning UI")
        self.malformed = MalformedInputs(self, self.diagnostics)
        self.lock = threading.Lock()  # guards the command queue (filled by the server thread)
        self.commands: collections.deque = collections.deque()
        self.estops: list = []  # replies of e-stops from the pages not yet sent on (they go first, coalesced)
        self.estop_call = None  # the e-stop call in flight: {"future", "sent", "deadline", "replies", "again"}
        self.pending_calls: list = []  # (deadline, future, what, reply)

        # -- live state (executor thread only) --
        self.decoder, self.force_decoder = JointStateDecoder(), JointStateDecoder()
        self.columns = JointColumns()
        self.raw = {"joints": [], "poses": [], "forces": []}
        self.seen: dict[str, float] = {}  # stream -> wall time last received
        every = max(1, round(500.0 / self.plot_rate))
        self.decimators = {"joints": model.Decimator(every), "forces": model.Decimator(every)}
        self.buffers = {k: model.StreamBuffer(keep) for k in ("joints", "poses", "forces")}
        self.latest = {}  # joints: (stamp, positions[12]); estimate: (stamp, pose)
        self.plots = {"joints": [], "forces": []}  # decimated rows since the last frame
        self.vibration = None  # latest VibrationReport
        self.node_status: dict[str, dict] = {}  # /diagnostics name -> level, message, values, seen
        self.diag_seq = 0
        self.events: collections.deque = collections.deque(maxlen=EVENTS_KEPT)
        self.event_seq = 0
        self.mcap = {"path": None, "state": "unknown", "seen": None}
        self.move = None  # target, sent (wall), status, held_since (stamp)
        self.run = None  # vibration being followed: t0, settings, nominal pose, source
        self.summary = None
        self.report_files: list[str] = []
        self.planner_settings = model.stream_defaults(self.robot)
        self.planner_known = False
        self.planner_ranges: dict = {}
        self.own_goal: bytes | None = None  # the id of the vibrate goal this page sent last

        # -- interfaces --
        self.move_client = ActionClient(self, MoveToPose, MOVE_ACTION)
        self.move_acceptances = GoalAcceptances(self, MOVE_ACTION)
        self.streams = []  # the 500 Hz subscriptions: only while a page is open or a move / vibration is followed
        self.unwatched_since = time.monotonic()
        self.create_subscription(VibrationUnitsStatus, "vibration/status", self._on_status, STATUS_QOS, raw=True)
        self.create_subscription(DiagnosticArray, "/diagnostics", self._on_diagnostics, 50, raw=True)
        self.clients_ = {
            "plan_path": self.create_client(PlanPath, "kinematics/plan_path"),
            "get": self.create_client(GetParameters, "vibration_planner/get_parameters"),
            "describe": self.create_client(DescribeParameters, "vibration_planner/describe_parameters"),
            # cancel every vibrate goal, whoever sent it (the action protocol: a zero goal id and stamp)
            "stop": self.create_client(CancelGoal, "vibration_planner/vibrate/_action/cancel_goal"),
            "estop": self.create_client(Trigger, "hardware_emulator/emergency_stop"),
            "reset": self.create_client(Trigger, "hardware_emulator/reset"),
        }
        self.vibrate_client = ActionClient(self, Vibrate, "vibration_planner/vibrate")
        self.vibrate_acceptances = GoalAcceptances(self, "vibration_planner/vibrate")
        # every vibration's feedback, whoever started it: the plan to follow and what the sensors show delivered
        self.create_subscription(Vibrate.Impl.FeedbackMessage, "vibration_planner/vibrate/_action/feedback",
                                 self._on_vibration_feedback, 10)
        self.vibration_feedback = None  # the latest Vibrate feedback (any client's goal)
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(1.0 / self.frame_rate, self._frame, clock=steady)
        # rclpy's EventsExecutor has no guard conditions: the queue is polled (an e-stop waits <= 10 ms)
        self.command_timer = self.create_timer(COMMAND_POLL_S, self._run_commands, clock=steady)
        self.command_timer.cancel()  # runs only while a page is open (commands come from pages)
        self.create_timer(2.0, self._slow_tick, clock=steady)
        self.server = UiServer(sock, self.token, self, command_rate=command_rate, log=self.get_logger().warning)
        self.server.start()
        self.diagnostics.set(OK, "serving", url=f"http://{host}:{self.server.port}/")  # never the token
        self.get_logger().info(f"planning UI at {self.server.url}")

    def shutdown(self) -> None:
        self.server.stop()

    # ==== inputs (executor thread) =====================================================================
    def _raw(self, stream: str, data: bytes) -> None:
        self.raw[stream].append(data)

    def _on_status(self, data: bytes) -> None:
        report = self.malformed.read("vibration/status", vibration_report_from_cdr, data)
        if report is None:
            return
        previous, self.vibration = self.vibration, report
        self.seen["vibration/status"] = time.monotonic()
        if previous is not None and report.event_seq != previous.event_seq and report.event in ("refused",
                                                                                               "safety_ramp"):
            self._event("hardware_emulator", f"vibration units: {report.event_text}", "WARN")
        if previous is not None and report.state != previous.state and report.state in ("estopped", "stopped"):
            self._event("hardware_emulator", f"vibration units {report.message}",
                        "ERROR" if report.state == "estopped" else "WARN")
        run = self.run
        if run is not None and not run.get("done") and report.state not in RUNNING_STATES \
                and report.since >= run["t0"] - 1e-6 and report.time > run["t0"]:
            run["done"] = True
            self._summarize(run, report.since)

    def _on_diagnostics(self, data: bytes) -> None:
        now = time.monotonic()
        statuses, errors = statuses_from_cdr(data)
        for error in errors:
            self.malformed.refuse("/diagnostics", error)
        for status in statuses:
            if status.name not in self.node_status and len(self.node_status) >= MAX_NODE_STATUSES:
                self.malformed.refuse("/diagnostics", MalformedMessageError(
                    f"more than {MAX_NODE_STATUSES} status names; {status.name[:60]!r} ignored", field="name",
                    kind="length"))
                continue
            self.diag_seq += 1
            level, values = status.level, dict(status.values)
            before = self.node_status.get(status.name)
            self.node_status[status.name] = {"level": level, "message": status.message, "values": values,
                                             "seen": now, "seq": self.diag_seq}
            node = status.node
            changed = before is None or before["message"] != status.message
            if changed and level >= 1 and status.name != self.diagnostics._name:
                self._event(node, status.message, LEVELS.get(level, "ERROR"))
            try:
                if node == "mcap_recorder":  # the file being written (also for a page opened after it started)
                    self._follow_recorder(status)
            except MalformedMessageError as exc:
                self.malformed.refuse("/diagnostics", exc)

    def _follow_recorder(self, status) -> None:
        files = recorder_files(status)
        path, last = files.path, files.last_file
        current = {"path": path, "state": "recording"} if path else ({"path": last, "state": "finished"} if last
                                                                      else None)
        if current and (self.mcap is None or (self.mcap["path"], self.mcap["state"]) != (current["path"],
                                                                                          current["state"])):
            self.mcap = {**current, "seen": time.monotonic()}
            self._list_report()

    def _event(self, source: str, text: str, level: str = "WARN") -> None:
        self.event_seq += 1
        self.events.append({"seq": self.event_seq, "wall": time.time(), "source": source, "level": level,
                            "text": text})

    # ==== live frames =================================================================================
    def _drain(self) -> None:
        now = time.monotonic()
        joints, self.raw["joints"] = self.raw["joints"], []
        if joints:
            self.seen["legs/joint_states"] = now
            self._decode_joints(joints)
        forces, self.raw["forces"] = self.raw["forces"], []
        if forces:
            self.seen["legs/force_estimate"] = now
            self._decode_forces(forces)
        poses, self.raw["poses"] = self.raw["poses"], []
        if poses:
            self.seen["platform/pose_estimate"] = now
            self._decode_poses(poses)

    def _decode_joints(self, messages) -> None:
        batches, _ = decode_joint_states_dropping_malformed(
            messages, self.decoder, lambda r: self.malformed.refuse("legs/joint_states", MalformedMessageError(r)))
        for batch in batches:
            legs, vib = self.columns(batch.names)
            if legs is None or vib is None:
                self.malformed.refuse("legs/joint_states", MalformedMessageError(
                    f"names {list(batch.names)[:14]} lack a leg_* or vib_* or repeat one", field="name",
                    kind="names"), len(batch.stamps))
                continue
            cols = np.concatenate([legs, vib])
            rows = np.concatenate([batch.position[:, cols], batch.effort[:, cols]], axis=1)
            self.buffers["joints"].add(batch.stamps, rows)
            self.latest["joints"] = (batch.stamps[-1], rows[-1])
            keep = self.decimators["joints"].take(len(batch.stamps))
            for i in keep:  # t, vib_1..6 (um), measured axial force leg_1..6 (N)
                self.plots["joints"].append([batch.stamps[i], *(rows[i, 6:12] * 1e6), *rows[i, 12:18]])

    def _decode_forces(self, messages) -> None:
        batches, _ = decode_joint_states_dropping_malformed(
            messages, self.force_decoder, lambda r: self.malformed.refuse("legs/force_estimate",
                                                                          MalformedMessageError(r)))
        for batch in batches:
            legs, _ = self.columns(batch.names)
            if legs is None:
                self.malformed.refuse("legs/force_estimate", MalformedMessageError(
                    f"names {list(batch.names)[:14]} lack a leg_* or repeat one", field="name", kind="names"),
                    len(batch.stamps))
                continue
            effort = batch.effort[:, legs]
            self.buffers["forces"].add(batch.stamps, effort)
            for i in self.decimators["forces"].take(len(batch.stamps)):
                self.plots["forces"].append([batch.stamps[i], *effort[i]])

    def _decode_poses(self, messages) -> None:
        batch = poses_from_cdr(messages, "pose estimate")
        for error in batch.errors:
            self.malformed.refuse("platform/pose_estimate", error)
        if not len(batch.kept):
            return
        stamps, poses = batch.stamps, batch.values
        self.buffers["poses"].add(stamps, poses)
        self.latest["estimate"] = (stamps[-1], poses[-1])
        self._follow_move(stamps, poses)

    def _follow_move(self, stamps, poses) -> None:
        move = self.move
        if move is None or move["status"] not in ("moving",):
            return
        for stamp, pose in zip(stamps, poses, strict=True):
            position, angle = model.pose_error(pose, move["target"])
            if position < SETTLE_POSITION_M and angle < SETTLE_ANGLE_RAD:
                move["held_since"] = stamp if move.get("held_since") is None else move["held_since"]
                if stamp - move["held_since"] >= SETTLE_HOLD_S:
                    move["status"] = "settled"
                    move["settled_after_s"] = time.monotonic() - move["sent"]
                    break
            else:
                move["held_since"] = None

    def _watch_streams(self) -> None:
        """Subscribe the 500 Hz streams while a page is open, or a move or vibration it started is being
        followed; drop them STREAMS_IDLE_S after that (nobody watching costs the suite nothing)."""
        now = time.monotonic()
        following = (self.move is not None and self.move["status"] == "moving") or \
            (self.run is not None and not self.run.get("done") and self.run["source"] == "this page")
        if self.server.clients and self.command_timer.is_canceled():
            self.command_timer.reset()
        elif not self.server.clients and not self.command_timer.is_canceled():
            self._run_commands()
            self.command_timer.cancel()
        if self.server.clients or following:
            self.unwatched_since = now
            if not self.streams:
                raw = [("legs/joint_states", JointState, lambda d: self._raw("joints", d)),
                       ("platform/pose_estimate", PoseStamped, lambda d: self._raw("poses", d)),
                       ("legs/force_estimate", JointState, lambda d: self._raw("forces", d))]
                self.streams = [self.create_subscription(kind, topic, callback, STREAM_QOS, raw=True)
                                for topic, kind, callback in raw]
        elif self.streams and now - self.unwatched_since > STREAMS_IDLE_S:
            for sub in self.streams:
                self.destroy_subscription(sub)
            self.streams = []
            self.latest.pop("estimate", None)

    def _frame(self) -> None:
        self._watch_streams()
        self._drain()
        self._expire()
        if not self.server.clients:  # nobody to show it to
            self.plots = {"joints": [], "forces": []}
            return
        now = time.monotonic()
        frame = {"type": "frame", "wall": time.time(), "stale_after_s": self.stale_after,
                 "ages": {k: now - t for k, t in self.seen.items()},
                 "plots": {k: np.round(np.asarray(v), 4).tolist() for k, v in self.plots.items()}}
        self.plots = {"joints": [], "forces": []}
        for key in ("estimate",):
            if key in self.latest:
                stamp, pose = self.latest[key]
                frame[key] = {"stamp": stamp, "fields": model.pose_fields(pose),
                              "points_mm": (model.platform_points(self.robot, pose) * 1e3).tolist()}
        if "joints" in self.latest:
            stamp, row = self.latest["joints"]
            frame["legs"] = {"stamp": stamp, "length_mm": ((row[:6] + row[6:12]) * 1e3).tolist(),
                             "vib_um": (row[6:12] * 1e6).tolist(), "force_n": row[12:18].tolist()}
        if self.move is not None:
            move = dict(self.move)
            if "estimate" in self.latest:
                position, angle = model.pose_error(self.latest["estimate"][1], move["target"])
                move.update(error_um=position * 1e6, error_deg=math.degrees(angle))
            move["target"] = model.pose_fields(move["target"])
            move["elapsed_s"] = now - move.pop("sent")
            frame["move"] = move
        frame["vibration"] = self._vibration_view()
        frame["nodes"] = [{"name": name, "level": LEVELS.get(s["level"], str(s["level"])), "message": s["message"],
                           "age_s": now - s["seen"]} for name, s in sorted(self.node_status.items())]
        frame["mcap"] = {"path": self.mcap["path"], "state": self.mcap["state"]}
        frame["events"] = list(self.events)
        frame["summary"] = self.summary
        frame["report"] = self.report_files
        frame["planner_known"] = self.planner_known
        self.server.broadcast(model.jsonable(frame))

    def _vibration_view(self) -> dict | None:
        r = self.vibration
        if r is None:
            return None
        planner = self.node_status.get("vibration_planner: vibration planner", {})
        return {"state": r.state, "level": r.level, "reason": r.reason, "since_s": r.since, "time_s": r.time,
                "amplitude_um": (r.amplitude * 1e6).tolist(), "event": r.event_text,
                "event_outcome": r.event_outcome, "accepted": r.accepted,
                "refused": r.refused, "estopped": r.state == "estopped",
                "planner": planner.get("values", {}).get("state"), "planner_message": planner.get("message"),
                "delivered": self._delivered_view()}

    def _delivered_view(self) -> dict | None:
        """What the latest vibration feedback says the sensors show delivered (None before any)."""
        f = self.vibration_feedback
        if f is None:
            return None
        return {"elapsed_s": f.elapsed_s, "frequency_hz": f.frequency_hz,
                "amplitude_um": f.delivered_amplitude_m * 1e6,
                "direction_error_deg": float(np.degrees(f.direction_error_rad)),
                "phase_spread_deg": float(np.degrees(f.phase_spread_rad))}

    def _slow_tick(self) -> None:
        if not self.planner_known:
            self._fetch_planner()
        self._list_report()

    def _list_report(self) -> None:
        path = self.mcap["path"]
        folder = Path(path).parent / "report" if path else None
        try:
            self.report_files = sorted(p.name for p in folder.iterdir() if p.suffix in (".png", ".md", ".json")) \
                if folder is not None and folder.is_dir() else []
        except OSError:  # a path the recorder named that cannot be listed (gone, unreadable, too long)
            self.report_files = []

    def _on_vibration_feedback(self, msg) -> None:
        """A vibration's feedback (this page's goal or another client's: the runner, ros2 action send_goal):
        follow a new plan for the summary, keep the delivered figures for the page."""
        feedback = msg.feedback
        self.vibration_feedback = feedback
        plan = plan_record(feedback.plan)
        if self.run is not None and abs(self.run["t0"] - plan["t0_s"]) < 1e-6:
            return
        ours = bytes(msg.goal_id.uuid) == self.own_goal
        self.run = {"t0": plan["t0_s"], "settings": settings_of_plan(plan), "nominal": np.asarray(plan["pose"]),
                    "source": "this page" if ours else "another client"}

    def _summarize(self, run: dict, ended: float) -> None:
        if run.get("settings") is None or run.get("nominal") is None:
            return
        try:
            summary = model.run_summary(self.robot, self.buffers["joints"], self.buffers["poses"],
                                        self.buffers["forces"], run["nominal"], run["settings"], run["t0"], ended)
            summary["source"] = run["source"]
            self.summary = summary
        except Exception as exc:  # noqa: BLE001 - e.g. too short to analyse: say so on the page
            self.summary = {"t0_s": run["t0"], "ended_s": ended, "error": f"{type(exc).__name__}: {exc}"}

    # ==== server backend (server thread) ==============================================================
    def hello(self) -> dict:
        robot, lim, unit = self.robot, self.robot.limits, self.robot.vibration_unit
        return model.jsonable({
            "convention": model.CONVENTION, "namespace": self.get_namespace(),
            "robot": {"base_points_mm": robot.base_hinges * 1e3, "platform_hinges_mm": robot.platform_hinges * 1e3,
                      "home": model.pose_fields(robot.home_pose), "stroke_mm": [lim.stroke_min * 1e3,
                                                                                lim.stroke_max * 1e3],
                      "unit": {"acceleration_max_g": unit.acceleration_max / STANDARD_GRAVITY,
                               "amplitude_max_um": unit.amplitude_max * 1e6,
                               "frequency_band_hz": [unit.frequency_min, unit.frequency_max]}},
            "paper_pose": model.pose_fields(paper_pose(robot)), "settle": {"position_um": SETTLE_POSITION_M * 1e6,
                                                                        "angle_deg": math.degrees(SETTLE_ANGLE_RAD)},
        })

    def command(self, cmd: str, args: dict, reply) -> None:
        with self.lock:
            if cmd == "estop":  # never behind another command: sent first, coalesced (_send_estops)
                self.estops.append(reply)
            else:
                self.commands.append((cmd, args, reply))

    def file(self, kind: str, name: str) -> Path | None:
        if kind != "report" or name not in self.report_files or not self.mcap["path"]:
            return None
        return Path(self.mcap["path"]).parent / "report" / name

    # ==== commands (executor thread) ==================================================================
    def _run_commands(self) -> None:
        self._send_estops()
        if not self.commands:
            return
        while True:
            self._send_estops()  # an e-stop that came meanwhile goes before the next command
            with self.lock:
                if not self.commands:
                    return
                cmd, args, reply = self.commands.popleft()
            try:
                getattr(self, f"_cmd_{cmd}")(args, reply)
            except StewartError as exc:
                reply({"ok": False, "refused_by": "planning_ui", "message": f"{type(exc).__name__}: {exc}"})
            except Exception as exc:  # noqa: BLE001 - a bug must not kill the node; the page says what failed
                self.get_logger().error(f"command {cmd} failed: {type(exc).__name__}: {exc}")
                reply({"ok": False, "refused_by": "planning_ui", "message": f"internal error: {exc}"})

    def _cmd_check_pose(self, args, reply) -> None:
        result = model.reachability(self.robot, model.pose_from_fields(args))
        reply({"ok": True, "message": "reachable" if result["reachable"] else result["error"]["message"], **result})

    def _cmd_plan_path(self, args, reply) -> None:
        goal = model.pose_from_fields(args)
        request = PlanPath.Request(waypoints=[pose_stamped(goal, self.get_clock().now().to_msg())])  # from the estimate

        def done(response):
            name = outcome_name(response.outcome.code)
            if name == "SUCCEEDED":
                poses = [pose_from_msg(p.pose) for p in response.path.poses]
                reply({"ok": True, "message": f"path of {len(poses)} waypoints",
                       "path": model.path_margins(self.robot, np.array(poses))})
            else:
                reply({"ok": False, "refused_by": "kinematics", "outcome": name,
                       "message": f"{name}: {response.outcome.message}", "path": {"waypoints": 0}})

        self._call("plan_path", request, done, reply)

    def _cmd_move(self, args, reply) -> None:
        target = model.pose_from_fields(args)
        check = model.reachability(self.robot, target)
        if not check["reachable"]:
            # refused here (nothing is sent); the kinematics node's own reason, asked with a plan_path
            # (which moves nothing), is shown beside ours
            error = check["error"]

            def with_node_reason(result):
                reply({"ok": False, "refused_by": "planning_ui (core check_pose)", "error": error,
                       "message": f"not sent: {error['type']}: {error['message']}",
                       "node_reason": result.get("message"), "check": check})

            self._cmd_plan_path(args, with_node_reason)
            return
        if not self.move_client.server_is_ready():
            reply({"ok": False, "refused_by": "planning_ui", "message": f"the {MOVE_ACTION} action is not available "
                   "(is the kinematics node running?)"})
            return
        move = {"target": target, "sent": time.monotonic(), "status": "moving", "held_since": None}
        self.move = move

        def on_feedback(msg) -> None:
            move["progress"] = float(msg.feedback.progress)

        def on_result(future) -> None:
            answer = future.result()
            if answer is None:
                return
            result = move_result_record(answer.result)
            move["outcome"], move["peak_force_n"] = result["outcome"], result["peak_force_n"]
            if result["outcome"] != "SUCCEEDED":
                move["status"], move["reason"] = f"ended {result['outcome']}", result["message"]
                self._event("kinematics", f"move {result['outcome']}: {result['message']}", "WARN")

        def on_goal(future) -> None:
            if future.exception() is not None or not future.result().accepted:
                move["status"], move["reason"] = "not taken", "kinematics did not take the goal"
                return
            future.result().get_result_async().add_done_callback(on_result)

        send_goal_recovering_async(self.move_client, move_goal(target), self.move_acceptances,
                                   feedback_callback=on_feedback).add_done_callback(on_goal)
        fields = model.pose_fields(target)
        self._event("planning_ui", "move goal sent: " + ", ".join(f"{k} {v:.3f}" for k, v in fields.items()), "OK")
        reply({"ok": True, "message": f"move goal sent to kinematics ({MOVE_ACTION}); following the move",
               "check": check})

    def _vibration_settings(self, args) -> tuple[dict, dict]:
        """(the page's vibration, every setting with it: the planner's streaming parameters and the defaults of
        what the page left out)."""
        params = model.vibration_from_fields(args)
        return params, {**default_settings(self.robot), **self.planner_settings, **params}

    def _estimate(self) -> np.ndarray:
        if "estimate" not in self.latest or time.monotonic() - self.seen.get("platform/pose_estimate", 0) > 1.0:
            raise StewartError("no recent platform/pose_estimate (is the kinematics node running?)")
        return self.latest["estimate"][1]

    def _cmd_preview_vibration(self, args, reply) -> None:
        _, settings = self._vibration_settings(args)
        preview = model.vibration_preview(self.robot, self._estimate(), settings, self.planner_ranges)
        reply({"ok": True, "message": "feasible" if preview["feasible"] else preview["reason"],
               "preview": preview, "planner_settings_known": self.planner_known})

    def _cmd_start(self, args, reply) -> None:
        params, settings = self._vibration_settings(args)
        pose = self._estimate()
        move = self.move
        if move is not None and move["status"] == "moving" and time.monotonic() - move["sent"] < MOVE_TIMEOUT_S:
            reply({"ok": False, "refused_by": "planning_ui", "message": "not started: the platform is still moving "
                   "to its target (start when the move has settled)"})
            return
        preview = model.vibration_preview(self.robot, pose, settings, self.planner_ranges)
        if not preview["feasible"]:
            reply({"ok": False, "refused_by": "planning_ui (core checks)", "message": f"not started: "
                   f"{preview['reason']}", "preview": preview})
            return
        if not self.vibrate_client.server_is_ready():
            reply({"ok": False, "refused_by": "planning_ui", "message": "the vibration_planner/vibrate action is not "
                   "available (is the vibration planner running?)"})
            return
        vibration = {k: settings[k] for k in VIBRATION_KEYS}
        answered = {"done": False}

        def answer(payload: dict) -> None:
            if not answered["done"]:
                answered["done"] = True
                reply(payload)

        def on_feedback(msg) -> None:  # the first feedback carries the plan: the vibration started
            if answered["done"]:
                return
            plan = plan_record(msg.feedback.plan)  # the run is followed from the feedback topic (every goal's)
            match = float(np.abs(np.asarray(plan["leg_amplitudes_m"]) * 1e6 - preview["leg_amplitudes_um"]).max())
            text = (f"started: {plan['frequency_hz']:g} Hz, platform amplitude {plan['amplitude_m'] * 1e6:.3f} um "
                    f"along {np.round(plan['direction_base'], 6).tolist()} (base frame), t0 = {plan['t0_s']:.6f} s")
            self._event("vibration_planner", text, "OK")
            answer({"ok": True, "message": text, "plan": plan, "preview": preview, "preview_vs_plan_um": match})

        def on_result(future) -> None:
            result = future.result()
            if result is None:
                return
            code = result.result.outcome
            if code.code != code.SUCCEEDED:
                self._event("vibration_planner", f"{outcome_name(code.code)}: {code.message}", "WARN")
            answer({"ok": False, "refused_by": "vibration_planner", "outcome": outcome_name(code.code),
                    "message": code.message, "preview": preview})

        def on_goal(future) -> None:
            if future.exception() is not None or not future.result().accepted:
                answer({"ok": False, "refused_by": "vibration_planner", "message": "the goal was not accepted"})
                return
            self.own_goal = bytes(future.result().goal_id.uuid)
            future.result().get_result_async().add_done_callback(on_result)

        send_goal_recovering_async(self.vibrate_client, goal_message(vibration), self.vibrate_acceptances,
                                   feedback_callback=on_feedback).add_done_callback(on_goal)

    def _trigger(self, name: str, reply) -> None:
        def done(response):
            reply({"ok": bool(response.success), "message": response.message,
                   **({} if response.success else {"refused_by": self.clients_[name].srv_name.split("/")[-2]})})
        self._call(name, Trigger.Request(), done, reply)

    def _cmd_stop(self, args, reply) -> None:
        """Cancel every vibration (the units ramp out), whichever client started it."""
        def done(response):
            canceling = len(response.goals_canceling)
            reply({"ok": response.return_code == CancelGoal.Response.ERROR_NONE or canceling == 0,
                   "message": f"cancelling {canceling} vibration(s): the units ramp out" if canceling else
                   "no vibration is running"})
        self._call("stop", CancelGoal.Request(), done, reply)

    def _send_estops(self) -> None:
        """The pages' e-stops, first and coalesced: one hardware_emulator/emergency_stop call at a time, sent again
        every ESTOP_RESEND_S while unanswered (it is idempotent; an answer can be lost), failed after
        CALL_TIMEOUT_S. E-stops that come while a call is in flight share one more call after it, so each is
        answered by a call sent after it came (a reset between two e-stops cannot swallow the second)."""
        with self.lock:
            replies, self.estops = self.estops, []
        call = self.estop_call
        if replies and call is not None:
            call["again"].extend(replies)
        elif replies:
            self._estop_call(replies)
        call = self.estop_call
        if call is None:
            return
        now, client = time.monotonic(), self.clients_["estop"]
        if now >= call["deadline"]:
            self.estop_call = None
            client.remove_pending_request(call["future"])
            for reply in call["replies"] + call["again"]:
                reply({"ok": False, "refused_by": "planning_ui", "message": f"no answer from {client.srv_name} "
                       f"within {CALL_TIMEOUT_S} s"})
        elif now - call["sent"] >= ESTOP_RESEND_S:
            client.remove_pending_request(call["future"])
            call["future"], call["sent"] = client.call_async(Trigger.Request()), now
            call["future"].add_done_callback(self._estop_answered)

    def _estop_call(self, replies: list) -> None:
        client = self.clients_["estop"]
        self._event("planning_ui", "emergency stop requested from the page", "ERROR")
        if not client.service_is_ready():
            for reply in replies:
                reply({"ok": False, "refused_by": "planning_ui",
                       "message": f"service {client.srv_name} is not available (is its node running?)"})
            return
        now = time.monotonic()
        self.estop_call = {"future": client.call_async(Trigger.Request()), "sent": now, "replies": replies,
                           "deadline": now + CALL_TIMEOUT_S, "again": []}
        self.estop_call["future"].add_done_callback(self._estop_answered)

    def _estop_answered(self, future) -> None:
        call = self.estop_call
        if call is None or future is not call["future"]:
            return  # an earlier send of a call that was sent again, or one given up
        self.estop_call = None
        if future.cancelled() or future.exception() is not None:
            result = {"ok": False, "refused_by": "planning_ui", "message": f"emergency_stop failed: "
                      f"{future.exception()}"}
        else:
            response = future.result()
            result = {"ok": bool(response.success), "message": response.message,
                      **({} if response.success else {"refused_by": "hardware_emulator"})}
        for reply in call["replies"]:
            reply(result)
        if call["again"]:
            self._estop_call(call["again"])

    def _cmd_reset(self, args, reply) -> None:
        self._trigger("reset", reply)

    # ==== service plumbing ============================================================================
    def _call(self, name: str, request, done, reply) -> None:
        client = self.clients_[name]
        if not client.service_is_ready():
            reply({"ok": False, "refused_by": "planning_ui",
                   "message": f"service {client.srv_name} is not available (is its node running?)"})
            return
        future = client.call_async(request)
        self.pending_calls.append((time.monotonic() + CALL_TIMEOUT_S, future, client.srv_name, reply))

        def finished(f):
            self.pending_calls[:] = [p for p in self.pending_calls if p[1] is not f]
            if f.cancelled() or f.exception() is not None:
                reply({"ok": False, "refused_by": "planning_ui", "message": f"{client.srv_name} failed: "
                       f"{f.exception()}"})
                return
            try:
                done(f.result())
            except StewartError as exc:
                reply({"ok": False, "refused_by": "planning_ui", "message": f"{type(exc).__name__}: {exc}"})
            except Exception as exc:  # noqa: BLE001 - a bug must not kill the node (this runs in the executor)
                self.get_logger().error(f"answer of {client.srv_name} not handled: {type(exc).__name__}: {exc}")
                reply({"ok": False, "refused_by": "planning_ui", "message": f"internal error: {exc}"})

        future.add_done_callback(finished)

    def _expire(self) -> None:
        now = time.monotonic()
        for call in [c for c in self.pending_calls if c[0] < now]:
            self.pending_calls.remove(call)
            call[3]({"ok": False, "refused_by": "planning_ui", "message": f"no answer from {call[2]} within "
                                                                           f"{CALL_TIMEOUT_S} s"})
        self._send_estops()  # an e-stop's resend and time-out also when no page is open any more

    def _fetch_planner(self) -> None:
        """The planner's current settings and declared ranges (for the preview's checks)."""
        def got(settings):
            self.planner_settings.update({k: v for k, v in settings.items() if k in STREAM_KEYS})
            self.planner_known = True

        self._get_planner_settings(got)
        names = list(STREAM_KEYS)
        describe = self.clients_["describe"]
        if describe.service_is_ready():
            def described(f):
                if f.exception() is None:
                    self.planner_ranges = {
                        d.name: (d.floating_point_range[0].from_value, d.floating_point_range[0].to_value)
                        for d in f.result().descriptors if d.name in names and d.floating_point_range and
                        math.isfinite(d.floating_point_range[0].from_value) and
                        math.isfinite(d.floating_point_range[0].to_value)}
            describe.call_async(DescribeParameters.Request(names=names)).add_done_callback(described)

    def _get_planner_settings(self, then) -> None:
        client = self.clients_["get"]
        if not client.service_is_ready():
            return

        def got(f):
            if f.exception() is not None:
                return
            try:
                then(planner_settings(parameter_values(STREAM_KEYS, f.result().values)))
            except MalformedMessageError as exc:
                self.malformed.refuse("vibration_planner/get_parameters", exc)

        client.call_async(GetParameters.Request(names=list(STREAM_KEYS))).add_done_callback(got)


def parameter_values(names, values) -> dict:
    """{name: Python value} of a get_parameters answer (rcl_interfaces ParameterValue per asked name);
    MalformedMessageError when the counts differ or a value's type is unknown."""
    if len(values) != len(names):
        raise MalformedMessageError(f"{len(values)} values for {len(names)} names", field="values", kind="length")
    out = {}
    for name, value in zip(names, values, strict=True):
        try:
            python = parameter_value_to_python(value)
        except (RuntimeError, ValueError, TypeError) as exc:
            raise MalformedMessageError(f"{name}: {exc}", field=name, kind="type") from None
        out[name] = list(python) if hasattr(python, "tolist") or isinstance(python, (list, tuple)) else python
    return out


def main(args=None) -> int:
    """Run the planning_ui node until SIGINT / SIGTERM; returns the exit code (2: it cannot start)."""
    return run_node(PlanningUiNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
