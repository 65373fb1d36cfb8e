"""Bring-up of the whole suite in the pip world (what `stewart-vibration run` does).

Starts every node as its own process on sim time in one namespace and ROS
domain, waits until each is ready (topics flowing, services up: no fixed
sleeps), runs a scenario (move, vibrate, return), stops the recorder so the
MCAP is finished, stops every process (SIGINT, then SIGTERM/SIGKILL), and
returns the MCAP path and the event times for the summary.
"""

from __future__ import annotations

import glob
import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState
from rcl_interfaces.srv import SetParameters
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

from ..emulation.vibration_status import report_from_values
from ..interrupts import INTERRUPTS
from ..processes import (
    DDS_PROFILE_ENV,
    NodeProcess,
    apply_environment,
    dds_environment,
    ros_environment,
    start_python_module,
)
from ..robot import default_config_dir
from ..scenario import MoveStep, Scenario, VibrateStep
from ..suite import DEFAULT_NAMESPACE, OPTIONAL_NODES, SUITE_NODES, SUITE_PARAMS_FILE
from . import ensure_ament_prefix_path
from .common import pose_from_msg, pose_stamped
from .mcap_ros import make_executor


class StepFailed(RuntimeError):
    """A scenario step did not complete (with the reason)."""


CLEAN_EXITS = (0, -2, 130)  # normal exit, SIGINT
# planner refusals that only mean "not yet" (its clock or pose input has not arrived): start is retried
NOT_READY_YET = ("clock not running", "no platform/pose_estimate received yet", "pose estimate is")
SETTLE_AFTER_VIBRATION_S = 0.5  # sim s between a vibration's end and the next step (a move)


def recorder_stats(log_text: str) -> dict | None:
    """The recorder's counts of its last file from its log (the MCAP_RECORDER_STATS line)."""
    lines = [line for line in log_text.splitlines() if line.startswith("MCAP_RECORDER_STATS ")]
    return json.loads(lines[-1].split(" ", 1)[1]) if lines else None


@dataclass
class RunOptions:
    namespace: str = DEFAULT_NAMESPACE
    domain_id: int = 42
    real_time_factor: float = 1.0
    out_dir: Path = Path("runs")
    params_file: Path | None = None
    extra_nodes: tuple = ()  # OPTIONAL_NODES keys to start as well ("foxglove", "ui")
    tissue_config: str | None = None  # soft-tissue YAML for the emulator (applied) and kinematics (checked)
    settle_tolerance_m: float = 1e-5
    settle_tolerance_rad: float = np.radians(0.01)
    step_timeout_s: float = 120.0  # wall clock, per step
    progress: object = print


@dataclass
class RunRecord:
    """What happened: MCAP path, per-step results and event times (sim s)."""

    mcap_path: Path | None = None
    log_dir: Path | None = None
    moves: list = field(default_factory=list)  # dicts: name, target, pose_error_m, pose_error_deg, time
    vibrations: list = field(default_factory=list)  # dicts: parameters, start_time, stop_time, start_message
    interrupted: bool = False
    failures: list = field(default_factory=list)  # what went wrong outside the steps (exits, recorder)
    recorder_stats: dict | None = None  # the recorder's counts of its last file (received, written, dropped)
    restarts: list = field(default_factory=list)  # (node, exit code) of nodes restarted under --keep-running
    guard_stops: list = field(default_factory=list)  # dicts: target, time, guard (status values), stopped_pose


class SuiteRunner:
    """Owns the child processes and a client node (own Context) in the suite's namespace."""

    def __init__(self, options: RunOptions):
        self.options = options
        self.record = RunRecord()
        self.procs: list[NodeProcess] = []
        self.client = None
        self._dead: set[str] = set()

    # -- processes -------------------------------------------------------------
    def start(self) -> None:
        opts = self.options
        ensure_ament_prefix_path()
        env = ros_environment(opts.domain_id)
        opts.out_dir.mkdir(parents=True, exist_ok=True)
        self.record.log_dir = opts.out_dir / "logs"
        params = opts.params_file or default_config_dir() / SUITE_PARAMS_FILE
        common = ["--ros-args", "-r", f"__ns:={opts.namespace}", "--params-file", str(params)]
        extra = {  # the emulator is a lifecycle node: wait_ready() configures and activates it
            "hardware_emulator": ["-p", f"real_time_factor:={opts.real_time_factor}", "-p", "autostart:=false"],
            "mcap_recorder": ["-p", f"output_dir:={opts.out_dir.resolve()}"],
        }
        if opts.tissue_config:
            for name in ("hardware_emulator", "kinematics"):
                extra[name] = extra.get(name, []) + ["-p", f"tissue_config:={opts.tissue_config}"]
        for node in SUITE_NODES + [OPTIONAL_NODES[key] for key in opts.extra_nodes]:
            self.procs.append(start_python_module(node.name, node.module, common + extra.get(node.name, []), env,
                                                  self.record.log_dir))
        # the runner's own client gets the suite's DDS transport profile too (loopback only by default); Fast DDS
        # reads it when this process creates its first participant
        apply_environment(os.environ, dds_environment(os.environ.get(DDS_PROFILE_ENV)))
        self.context = Context()
        self.context.init(domain_id=opts.domain_id)
        self.client = Node("suite_runner", namespace=opts.namespace, context=self.context)
        self.executor = make_executor(self.context)  # EventsExecutor: a third of the CPU per message
        self.executor.add_node(self.client)
        self.clock = None
        self.latest = {}
        # depth 1: the runner only needs the latest sample and must not fall behind the suite
        self.client.create_subscription(Clock, "/clock", self._on_clock, 1)
        self.readiness_subs = []
        for topic, kind in (("platform/pose_estimate", PoseStamped), ("legs/force_estimate", JointState)):
            sub = self.client.create_subscription(kind, topic, lambda m, t=topic: self.latest.__setitem__(t, m), 1)
            self.readiness_subs.append(sub)
        self.target_pub = self.client.create_publisher(PoseStamped, "platform/target_pose", 10)
        self.vibration_status = None  # latest VibrationReport of the emulator
        self.status_history = []  # (state, since, reason) transitions seen
        self.planner_status = None  # latest planner DiagnosticStatus
        status_qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                                durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.client.create_subscription(DiagnosticStatus, "vibration/status", self._on_vibration_status, status_qos)
        self.client.create_subscription(DiagnosticArray, "/diagnostics", self._on_diagnostics, 50)
        self.guard_status = None  # latest kinematics/guard_status
        self.client.create_subscription(DiagnosticStatus, "kinematics/guard_status",
                                        lambda m: setattr(self, "guard_status", m), status_qos)

    def _on_clock(self, msg: Clock) -> None:
        self.clock = msg.clock.sec + msg.clock.nanosec * 1e-9

    def _on_vibration_status(self, msg: DiagnosticStatus) -> None:
        level = {DiagnosticStatus.OK: "ok", DiagnosticStatus.WARN: "warn"}.get(msg.level, "error")
        report = report_from_values(level, {kv.key: kv.value for kv in msg.values})
        if not self.status_history or self.status_history[-1][:2] != (report.state, report.since):
            self.status_history.append((report.state, report.since, report.reason))
        self.vibration_status = report

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.name.startswith("vibration_planner"):
                self.planner_status = status

    def stop(self) -> None:
        """Stop the recorder (finishes the MCAP), then every process; close the client. Records a failure
        for every node that exited abnormally or could not be stopped, and for recorder drops."""
        path = None
        if self.client is not None:
            try:
                res = self.call(Trigger, "mcap_recorder/stop", Trigger.Request(), timeout=10.0)
                self.options.progress(f"recorder: {res.message}")
                path = Path(res.message) if res.success else None
            except (TimeoutError, RuntimeError, StepFailed) as exc:
                self.options.progress(f"recorder stop service failed ({exc}); SIGINT finishes the file")
        for proc in reversed(self.procs):
            died = proc.popen.poll()
            if proc.name in self._dead:
                continue  # reported by supervise()
            code = proc.stop(grace_s=10.0)
            if code is None:
                self.record.failures.append(f"{proc.name} could not be stopped (log: {proc.log_path})")
            elif died is not None and died not in CLEAN_EXITS:
                self.record.failures.append(f"{proc.name} died during the run with exit code {died} "
                                            f"(log: {proc.log_path})")
            elif code not in CLEAN_EXITS:
                self.record.failures.append(f"{proc.name} exited with code {code} (log: {proc.log_path})")
            if proc.name == "mcap_recorder":
                self.record.recorder_stats = recorder_stats(proc.log_text())
        stats = self.record.recorder_stats
        if stats is not None and stats.get("dropped", 0):
            self.record.failures.append(f"the recorder dropped {stats['dropped']} of {stats['received']} messages")
        if self.client is not None:
            self.executor.shutdown()
            self.client.destroy_node()
            self.context.try_shutdown()
            self.client = None
        if path is None or not path.exists():
            files = sorted(glob.glob(str(self.options.out_dir / "*.mcap")), key=os.path.getmtime)
            path = Path(files[-1]) if files else None
        self.record.mcap_path = path

    def supervise(self, respawn: set[str]) -> None:
        """Keep the suite up until interrupted (--keep-running): a node that exits is reported and, when
        its name is in ``respawn``, started again with the same arguments; the others keep running."""
        progress = self.options.progress
        while True:
            for i, proc in enumerate(self.procs):
                code = proc.popen.poll()
                if code is None or proc.name in self._dead:
                    continue
                if proc.name in respawn:
                    progress(f"{proc.name} exited with code {code}; restarting it (log: {proc.log_path})")
                    self.record.restarts.append((proc.name, code))
                    self.procs[i] = proc.restart()
                else:
                    progress(f"{proc.name} exited with code {code}; not restarted (--respawn does not name it); "
                             "the other nodes keep running")
                    self.record.failures.append(f"{proc.name} exited with code {code} during --keep-running "
                                                f"(log: {proc.log_path})")
                    self._dead.add(proc.name)
            with INTERRUPTS.deferred():  # Ctrl-C must not land in rclpy's C++
                self.executor.spin_once(timeout_sec=0.5)

    # -- helpers -----------------------------------------------------------------
    def spin_until(self, predicate, timeout: float, what: str) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            dead = [p.name for p in self.procs if not p.alive()]
            if dead:
                raise StepFailed(f"{', '.join(dead)} died while waiting for {what} (see {self.record.log_dir})")
            if predicate():
                return
            with INTERRUPTS.deferred():
                self.executor.spin_once(timeout_sec=0.02)
        raise StepFailed(f"timed out after {timeout:.0f} s waiting for {what}")

    def call(self, srv_type, name: str, request, timeout: float = 30.0):
        client = self.client.create_client(srv_type, name)
        try:
            self.spin_until(client.service_is_ready, timeout, f"service {name}")
            future = client.call_async(request)
            self.spin_until(future.done, timeout, f"answer of {name}")
            return future.result()
        finally:
            self.client.destroy_client(client)

    def wait_sim(self, seconds: float, what: str) -> None:
        self.spin_until(lambda: self.clock is not None, 30, "/clock")
        end = self.clock + seconds
        rtf = max(self.options.real_time_factor, 0.05)
        self.spin_until(lambda: self.clock >= end, seconds / rtf + 60, what)

    # -- readiness ---------------------------------------------------------------
    def transition(self, node: str, transition_id: int, label: str) -> None:
        """Drive a lifecycle transition of ``node`` (lifecycle_msgs ChangeState); StepFailed if refused."""
        request = ChangeState.Request()
        request.transition.id = transition_id
        if not self.call(ChangeState, f"{node}/change_state", request, timeout=60.0).success:
            raise StepFailed(f"{node} refused the lifecycle transition '{label}' (see {self.record.log_dir})")

    def log_lines(self, node: str, marker: str) -> list[str]:
        """Lines of ``node``'s log that contain ``marker`` (e.g. the URL an optional node prints)."""
        proc = next((p for p in self.procs if p.name == node), None)
        return [line for line in proc.log_text().splitlines() if marker in line] if proc else []

    def wait_ready(self) -> None:
        ns = self.options.namespace.rstrip("/")
        progress = self.options.progress
        self.transition("hardware_emulator", Transition.TRANSITION_CONFIGURE, "configure")
        self.transition("hardware_emulator", Transition.TRANSITION_ACTIVATE, "activate")
        progress("ready: hardware_emulator configured and active (lifecycle)")
        self.spin_until(lambda: self.clock is not None, 60, "the emulator's /clock")
        progress("ready: hardware_emulator (/clock)")
        self.spin_until(lambda: "platform/pose_estimate" in self.latest, 60, "platform/pose_estimate")
        progress("ready: kinematics (pose estimates)")
        self.spin_until(lambda: "legs/force_estimate" in self.latest, 60, "legs/force_estimate")
        progress("ready: leg_force_estimator (force estimates)")
        for service in ("vibration_planner/start", "mcap_recorder/stop"):
            client = self.client.create_client(Trigger, service)
            self.spin_until(client.service_is_ready, 60, f"service {service}")
            self.client.destroy_client(client)
        progress("ready: vibration_planner, mcap_recorder (services)")

        def recorder_subscribed():
            infos = self.client.get_subscriptions_info_by_topic(f"{ns}/legs/joint_states")
            return any(i.node_name == "mcap_recorder" for i in infos)

        self.spin_until(recorder_subscribed, 60, "the recorder to subscribe to legs/joint_states")
        progress("ready: mcap_recorder is recording the suite's topics")
        for sub in self.readiness_subs:  # only the ground truth and /clock are needed from here on
            self.client.destroy_subscription(sub)

    # -- steps ---------------------------------------------------------------------
    def run(self, scenario: Scenario) -> RunRecord:
        for index, step in enumerate(scenario.steps, start=1):
            label = f"step {index}/{len(scenario.steps)}"
            if isinstance(step, MoveStep):
                self.move_to(step, label)
            elif isinstance(step, VibrateStep):
                self.vibrate(step, label)
        return self.record

    def move_to(self, step: MoveStep, label: str) -> None:
        opts = self.options
        opts.progress(f"{label}: move to {step.name} {np.round(step.pose, 5).tolist()}")
        start = self.clock
        # the 500 Hz ground truth only while a move settles: the runner must not load the machine
        self.latest.pop("platform/pose", None)
        ground_truth = self.client.create_subscription(
            PoseStamped, "platform/pose", lambda m: self.latest.__setitem__("platform/pose", m), 1)
        try:
            (self._guarded if step.guarded else self._settle)(step, label, start)
        finally:
            self.client.destroy_subscription(ground_truth)

    def _settle(self, step: MoveStep, label: str, start: float) -> None:
        """Send the target, then wait until the ground truth holds within tolerance for 0.5 s of sim time."""
        opts = self.options
        self.target_pub.publish(pose_stamped(step.pose, self.client.get_clock().now().to_msg()))
        held_since = [None]

        def settled():
            msg = self.latest.get("platform/pose")
            if msg is None or self.clock is None or self.clock < start + 0.1:
                return False
            err = pose_from_msg(msg.pose) - step.pose
            ok = np.abs(err[:3]).max() < opts.settle_tolerance_m and np.abs(err[3:]).max() < opts.settle_tolerance_rad
            if not ok:
                held_since[0] = None
                return False
            held_since[0] = held_since[0] or self.clock
            return self.clock - held_since[0] >= 0.5  # held for 0.5 s of sim time

        self.spin_until(settled, opts.step_timeout_s, f"the platform to settle at {step.name}")
        err = pose_from_msg(self.latest["platform/pose"].pose) - step.pose
        self.record.moves.append({
            "name": step.name, "target": step.pose.tolist(), "time": self.clock,
            "pose_error_m": float(np.abs(err[:3]).max()), "pose_error_deg": float(np.degrees(np.abs(err[3:]).max())),
        })
        opts.progress(f"{label}: settled at {step.name} in {self.clock - start:.2f} s sim; ground-truth error "
                      f"{np.abs(err[:3]).max() * 1e6:.3f} um, {np.degrees(np.abs(err[3:]).max()):.5f} deg")

    def _guarded(self, step: MoveStep, label: str, start: float) -> None:
        """A move the force guard must stop: send the target, wait for kinematics/guard_status to report a trip
        during it, then for the platform to come to rest short of the target (0.5 s of sim time still)."""
        opts = self.options
        self.target_pub.publish(pose_stamped(step.pose, self.client.get_clock().now().to_msg()))

        def values():
            status = self.guard_status
            return {kv.key: kv.value for kv in status.values} if status is not None else {}

        def tripped():
            v = values()
            return v.get("state") == "tripped" and v.get("trip_limit") in ("force", "moment") and \
                float(v.get("trip_time_s", -1.0)) >= start - 1e-6  # not a pause for late estimates

        def reached():
            msg = self.latest.get("platform/pose")
            tolerance = opts.settle_tolerance_m
            return msg is not None and np.abs(pose_from_msg(msg.pose)[:3] - step.pose[:3]).max() < tolerance

        self.spin_until(lambda: tripped() or reached(), opts.step_timeout_s, "the force guard to stop the move")
        if not tripped():
            raise StepFailed(f"the force guard did not stop the move to {np.round(step.pose, 5).tolist()}: the "
                             "platform reached the target")
        last, still = [None], [None]

        def at_rest():
            msg = self.latest.get("platform/pose")
            if msg is None:
                return False
            pose = pose_from_msg(msg.pose)
            if last[0] is None or np.abs(pose[:3] - last[0][:3]).max() > 1e-6:
                last[0], still[0] = pose, self.clock
                return False
            return self.clock - still[0] >= 0.5

        self.spin_until(at_rest, opts.step_timeout_s, "the platform to come to rest after the guard stop")
        held = last[0]
        record = {"target": step.pose.tolist(), "time": self.clock, "guard": values(), "stopped_pose": held.tolist(),
                  "short_of_target_m": float(np.linalg.norm(step.pose[:3] - held[:3]))}
        self.record.guard_stops.append(record)
        opts.progress(f"{label}: the force guard stopped the move as expected: {self.guard_status.message}; "
                      f"held {record['short_of_target_m'] * 1e3:.2f} mm short of the target")

    def vibrate(self, step: VibrateStep, label: str) -> None:
        """Set the planner's parameters, start, and follow the emulator's vibration/status until the
        vibration is over; an abort, a refusal or a vibration shorter than planned fails the step."""
        opts = self.options
        params = []
        for key, value in step.parameters.items():
            value = [float(v) for v in value] if isinstance(value, list) else value
            value = float(value) if isinstance(value, int) and not isinstance(value, bool) else value
            params.append(Parameter(key, value=value).to_parameter_msg())
        res = self.call(SetParameters, "vibration_planner/set_parameters", SetParameters.Request(parameters=params))
        refused = [f"{p.name}: {r.reason}" for p, r in zip(params, res.results, strict=True) if not r.successful]
        if refused:
            raise StepFailed(f"planner refused parameters: {'; '.join(refused)}")
        res = self.call(Trigger, "vibration_planner/start", Trigger.Request())
        deadline = time.monotonic() + 10.0
        while not res.success and res.message.startswith(NOT_READY_YET) and time.monotonic() < deadline:
            # a busy machine: the planner has no /clock or pose estimate yet -- not a reason to give up at once
            end = time.monotonic() + 0.5
            self.spin_until(lambda e=end: time.monotonic() >= e, 1.0, "a moment")
            res = self.call(Trigger, "vibration_planner/start", Trigger.Request())
        if not res.success:
            raise StepFailed(f"vibration start refused: {res.message}")
        ran = json.loads(res.message.rsplit("settings: ", 1)[1])
        start, t0 = self.clock, float(ran["t0_s"])
        ramp, duration = float(ran["ramp_s"]), float(ran["duration_s"])
        opts.progress(f"{label}: vibrating: {res.message.rsplit('; settings: ', 1)[0]}")
        record = {"parameters": ran, "start_time": start, "t0": t0, "start_message": res.message}
        self.record.vibrations.append(record)

        def failed() -> str | None:
            report, planner = self.vibration_status, self.planner_status
            if planner is not None and "aborted:" in planner.message:
                return f"the planner aborted the vibration: {planner.message}"
            if report is not None and report.state in ("estopped", "stopped") and report.since >= t0 - 1e-6:
                return f"the vibration units {report.message}"
            if report is not None and report.event.startswith("refused") and report.event_stamp is not None and \
                    abs(report.event_stamp - t0) < 1e-6:
                return f"the hardware emulator {report.event}"
            return None

        def watch(until: float, what: str) -> None:
            self.spin_until(lambda: failed() is not None or (self.clock is not None and self.clock >= until),
                            (until - self.clock) / max(opts.real_time_factor, 0.05) + 60, what)
            reason = failed()
            if reason:
                record["failure"] = reason
                raise StepFailed(reason)

        watch(t0 + ramp, "the vibration to begin")
        # the emulator reports at 10 Hz of wall time: faster than real time the newest report may predate t0, so
        # wait for one from t0 on and look for the start among the state changes seen (a short ramp-in can fall
        # between two reports)
        self.spin_until(lambda: failed() is not None or (self.vibration_status is not None and
                                                          self.vibration_status.time >= t0), 10.0,
                        "a vibration report from t0 on")
        report = self.vibration_status
        began = any(state in ("ramping_in", "running") and since >= t0 - 0.01
                    for state, since, _reason in self.status_history)
        if report is None or not began:
            reason = (f"the vibration did not begin at t0 = {t0:.3f} s: the emulator reports "
                      f"{report.message if report else 'nothing (no vibration/status)'}")
            record["failure"] = reason
            raise StepFailed(reason)
        watch(t0 + duration, "the vibration to finish")
        self.spin_until(lambda: failed() is not None or (self.vibration_status is not None and
                                                          self.vibration_status.state in ("idle", "stopped")),
                        30 / max(opts.real_time_factor, 0.05), "the units to come to rest")
        reason = failed()
        if reason:
            record["failure"] = reason
            raise StepFailed(reason)
        record["stop_time"] = self.clock
        ended = self.vibration_status.since
        record["status_active_s"] = ended - t0
        opts.progress(f"{label}: vibration done: the emulator reports the units active from t0 = {t0:.3f} s to "
                      f"{ended:.3f} s ({ended - t0:.3f} s of the planned {duration:.3f} s)")
        self.wait_sim(SETTLE_AFTER_VIBRATION_S, "the platform to settle after the vibration")
        if ended < t0 + duration - 0.05:
            reason = f"the vibration ended {t0 + duration - ended:.3f} s early: {self.vibration_status.message}"
            record["failure"] = reason
            raise StepFailed(reason)
