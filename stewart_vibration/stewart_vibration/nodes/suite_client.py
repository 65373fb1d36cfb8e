"""The main job's ROS client (its own rclpy Context, in the suite's namespace and domain): readiness and
the emulator's lifecycle, the topics, services and goals the scenario's steps use
(``runtime.suite_interface.SuiteClient``; the goals: ``suite_goals``), and the recorder's stop.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, cast

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState
from rclpy.context import Context
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from stewart_vibration_interfaces.msg import ForceGuardStatus, VibrationUnitsStatus
from stewart_vibration_interfaces.srv import StopRecording

from ..messages.stamped import pose_from_cdr
from ..messages.status_values import guard_status_from_cdr, statuses_from_cdr, vibration_report_from_cdr
from ..motion.estimate_watch import LAG_MEMORY_S
from ..motion.guard_status import GuardStatus
from ..runtime.interrupts import INTERRUPTS
from ..runtime.processes import DDS_PROFILE_ENV, apply_environment, dds_environment
from ..runtime.sim_clock import HeldFor
from ..runtime.suite_interface import IdentificationEnd, MoveResult, StepFailed, VibrationEnd, VibrationStart
from . import ensure_ament_prefix_path
from .diagnostics import MalformedInputs
from .message_conversions import stamp_seconds
from .outcomes import outcome_name
from .run_loop import STATUS_QOS, make_executor
from .service_calls import ServiceClients, answer_with_resend, transition_lifecycle
from .suite_goals import SuiteGoals

if TYPE_CHECKING:
    from rclpy.subscription import Subscription

    from ..emulation.vibration_status import VibrationReport

# the 500 Hz poses a settling move follows (raw, checked and decoded only when asked): topic -> what it is
FOLLOWED_POSES = {"ground_truth/platform_pose": "ground-truth pose", "platform/pose_estimate": "pose estimate"}
# before the first move the force estimates must have kept within ESTIMATES_CURRENT_S (sim s) of /clock for longer
# than the force guard remembers a lag (it slows moves by the largest lag of the last LAG_MEMORY_S; 0.15 s still
# allows 10 mm/s); at most ESTIMATES_CURRENT_WAIT_S of wall time, then the run goes on and says so
ESTIMATES_CURRENT_S = 0.15
ESTIMATES_CURRENT_WAIT_S = 60.0
RECORDED_BEFORE_READY = ("legs/joint_states", "legs/joint_trajectory", "vibration/joint_trajectory")  # by the recorder


class SuiteClient:
    """A client node of the running suite. ``dead()`` names nodes that died (a wait then fails at once)."""

    def __init__(self, namespace: str, domain_id: int, real_time_factor: float, dead: Callable[[], list[str]],
                 log_dir=None):
        ensure_ament_prefix_path()
        self.namespace, self.real_time_factor, self.dead, self.log_dir = namespace, real_time_factor, dead, log_dir
        # the runner's own client gets the suite's DDS transport profile too (loopback only by default); Fast DDS
        # reads it when this process creates its first participant
        apply_environment(os.environ, dds_environment(os.environ.get(DDS_PROFILE_ENV)))
        self.context = Context()
        self.context.init(domain_id=domain_id)
        self.node = Node("suite_runner", namespace=namespace, context=self.context)
        self.executor = make_executor(self.context)  # EventsExecutor: a third of the CPU per message
        self.clients = ServiceClients(self.node)  # one kept client per service (see nodes.service_calls)
        self.malformed = MalformedInputs(self.node, None)  # malformed messages: counted, logged, ignored
        self.executor.add_node(self.node)
        self.clock: float | None = None
        self.latest: dict = {}
        # depth 1: the runner only needs the latest sample and must not fall behind the suite
        self.node.create_subscription(Clock, "/clock", self._on_clock, 1)
        self.readiness_subs = [  # the ignore: mypy cannot type the lambda's bound default (t=topic)
            self.node.create_subscription(kind, topic,
                                          lambda m, t=topic: self.latest.__setitem__(t, m), 1)  # type: ignore[misc]
            for topic, kind in (("platform/pose_estimate", PoseStamped), ("legs/force_estimate", JointState))]
        self.goals = SuiteGoals(self.node, self.spin_until, self._wait_answer, self.dead)  # move, vibrate, identify
        self.vibration_status: VibrationReport | None = None  # latest VibrationReport of the emulator
        self.status_history: list = []  # (state, since, reason) transitions seen
        self.recorder_fault: str | None = None  # the recorder's write failure (its /diagnostics fault_reason)
        self.stopping = False  # set for the safe stop after a failure: waits then go on despite the fault
        self.recorder_ready_clock: float | None = None  # /clock when the recorder was seen recording the states
        self.node.create_subscription(VibrationUnitsStatus, "vibration/status", self._on_vibration_status, STATUS_QOS,
                                      raw=True)
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diagnostics, 50, raw=True)
        self._guard: GuardStatus | None = None  # latest well-formed kinematics/guard_status
        self.node.create_subscription(ForceGuardStatus, "kinematics/guard_status", self._on_guard_status, STATUS_QOS,
                                      raw=True)
        self._pose_subs: list[Subscription] = []  # the followed poses' subscriptions (follow_poses)
        self._raw_poses: dict[str, bytes] = {}  # topic -> its newest raw message while followed
        # topic -> (the raw message last decoded, its pose or the last good one)
        self._decoded: dict[str, tuple] = {topic: (None, None) for topic in FOLLOWED_POSES}

    # -- callbacks --------------------------------------------------------------------------------------
    def _on_clock(self, msg: Clock) -> None:
        self.clock = msg.clock.sec + msg.clock.nanosec * 1e-9

    def _on_vibration_status(self, data: bytes) -> None:
        report = self.malformed.read("vibration/status", vibration_report_from_cdr, data)
        if report is None:
            return
        if not self.status_history or self.status_history[-1][:2] != (report.state, report.since):
            self.status_history.append((report.state, report.since, report.reason))
        self.vibration_status = report

    def _on_diagnostics(self, data: bytes) -> None:
        statuses, errors = statuses_from_cdr(data)
        for error in errors:
            self.malformed.refuse("/diagnostics", error)
        for status in statuses:
            if status.name.startswith("mcap_recorder") and self.recorder_fault is None:
                if status.values.get("fault") == "write_failed":  # the typed field, not the message text
                    self.recorder_fault = status.values.get("fault_reason") or "write failed"

    def _on_guard_status(self, data: bytes) -> None:
        self._guard = self.malformed.read("kinematics/guard_status", guard_status_from_cdr, data) or self._guard

    # -- waiting ----------------------------------------------------------------------------------------
    def spin_until(self, predicate, timeout: float, what: str) -> None:
        """Spin until ``predicate()``; StepFailed after ``timeout`` (wall s), as soon as a node died, or when the
        recorder reports a write failure (unless ``stopping``): a run that is not recorded stops its scenario."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            dead = self.dead()
            if dead:
                raise StepFailed(f"{', '.join(dead)} died while waiting for {what} (see {self.log_dir})")
            if self.recording_failed():
                raise StepFailed(f"the recorder stopped recording while waiting for {what}: {self.recorder_fault}")
            if predicate():
                return
            with INTERRUPTS.deferred():  # Ctrl-C must not land in rclpy's C++
                self.executor.spin_once(timeout_sec=0.02)
        raise StepFailed(f"timed out after {timeout:.0f} s waiting for {what}")

    def recording_failed(self) -> bool:
        """Whether the recorder reported a write failure and the run is not already stopping because of one."""
        return self.recorder_fault is not None and not self.stopping

    def spin_once(self, timeout_s: float = 0.5) -> None:
        with INTERRUPTS.deferred():
            self.executor.spin_once(timeout_sec=timeout_s)

    def wait_sim(self, seconds: float, what: str) -> None:
        """Wait ``seconds`` of sim time."""
        self.spin_until(lambda: self.clock is not None, 30, "/clock")
        end = cast(float, self.clock) + seconds  # the clock runs (waited for above)
        rtf = max(self.real_time_factor, 0.05)
        self.spin_until(lambda: cast(float, self.clock) >= end, seconds / rtf + 60, what)

    def call(self, srv_type, name: str, request, timeout: float = 30.0):
        """Call service ``name`` and return its answer (idempotent ones asked again, see
        nodes.service_calls); StepFailed if it is not up or does not answer, or a node died."""
        client = self._ready_client(srv_type, name, timeout)
        answer = answer_with_resend(client, name, request, timeout, self._wait_answer(name))
        if answer is None:
            raise StepFailed(f"timed out after {timeout:.0f} s waiting for the answer of {name}")
        return answer

    # -- readiness ----------------------------------------------------------------------------------------
    def transition(self, node: str, transition_id: int, label: str, timeout: float = 60.0) -> None:
        """Drive a lifecycle transition of ``node`` (lifecycle_msgs ChangeState, sent once; a lost answer is
        recovered from its get_state); StepFailed if refused or unanswered."""
        name = f"{node}/change_state"
        client = self._ready_client(ChangeState, name, timeout)
        made = transition_lifecycle(client, transition_id, timeout, self._wait_answer(name),
                                    lambda: self.call(GetState, f"{node}/get_state", GetState.Request()
                                                      ).current_state.label)
        if made is None:
            raise StepFailed(f"timed out after {timeout:.0f} s waiting for {node} to '{label}' (see {self.log_dir})")
        if not made:
            raise StepFailed(f"{node} refused the lifecycle transition '{label}' (see {self.log_dir})")

    def _ready_client(self, srv_type, name: str, timeout: float):
        """The kept client of service ``name`` once the service is up; StepFailed if it is not."""
        client = self.clients.get(srv_type, name)
        self.spin_until(client.service_is_ready, timeout, f"service {name}")
        return client

    def _wait_answer(self, name: str):
        """``wait(predicate, seconds) -> bool`` for an answer of ``name``; a died node fails at once."""
        what = f"answer of {name}"

        def wait(predicate, seconds: float) -> bool:
            try:
                self.spin_until(predicate, seconds, what)
                return True
            except StepFailed:
                if self.dead() or self.recording_failed():
                    raise
                return False
        return wait

    def wait_ready(self, progress) -> None:
        """Configure and activate the emulator, then wait until every node works: /clock, pose and force
        estimates, the planner's and the recorder's services, the recorder subscribed to the states."""
        ns = self.namespace.rstrip("/")
        self.transition("hardware_emulator", Transition.TRANSITION_CONFIGURE, "configure")
        self.transition("hardware_emulator", Transition.TRANSITION_ACTIVATE, "activate")
        progress("ready: hardware_emulator configured and active (lifecycle)")
        self.spin_until(lambda: self.clock is not None, 60, "the emulator's /clock")
        progress("ready: hardware_emulator (/clock)")
        self.spin_until(lambda: "platform/pose_estimate" in self.latest, 60, "platform/pose_estimate")
        progress("ready: kinematics (pose estimates)")
        self.spin_until(lambda: "legs/force_estimate" in self.latest, 60, "legs/force_estimate")
        progress("ready: leg_force_estimator (force estimates)")
        self._ready_client(StopRecording, "mcap_recorder/stop", 60)
        self.spin_until(self.goals.vibrate_client.server_is_ready, 60, "the vibration_planner/vibrate action")
        progress("ready: vibration_planner (action), mcap_recorder (services)")

        def recorder_subscribed():  # the states, and the commands: a short vibration is one window
            return all(any(i.node_name == "mcap_recorder" for i in self.node.get_subscriptions_info_by_topic(
                f"{ns}/{topic}")) for topic in RECORDED_BEFORE_READY)

        self.spin_until(recorder_subscribed, 60, f"the recorder to subscribe to {', '.join(RECORDED_BEFORE_READY)}")
        self.recorder_ready_clock = self.clock
        progress("ready: mcap_recorder is recording the suite's topics")
        self._wait_estimates_current(progress)
        for sub in self.readiness_subs:  # only the ground truth and /clock are needed from here on
            self.node.destroy_subscription(sub)
        self.readiness_subs = []

    def _wait_estimates_current(self, progress) -> None:
        """Wait until the force estimates have stayed within ESTIMATES_CURRENT_S of /clock for LAG_MEMORY_S + 0.5 s
        of sim time (at most ESTIMATES_CURRENT_WAIT_S of wall time): an estimator still starting up makes the
        force guard plan the first move at a crawl (CI: `--real-time-factor 2` did not settle in 120 s)."""
        held = HeldFor(LAG_MEMORY_S + 0.5)

        def current() -> bool:
            msg, clock = self.latest.get("legs/force_estimate"), self.clock
            if msg is None or clock is None:
                return False
            return held.update(clock - stamp_seconds(msg.header.stamp) <= ESTIMATES_CURRENT_S, clock)

        try:
            self.spin_until(current, ESTIMATES_CURRENT_WAIT_S, "the force estimates to keep up with /clock")
            progress("ready: the force estimates keep up with the clock")
        except StepFailed:
            if self.dead() or self.recording_failed():
                raise
            progress(f"WARNING: the force estimates did not keep within {ESTIMATES_CURRENT_S} s of /clock for "
                     f"{ESTIMATES_CURRENT_WAIT_S:.0f} s (busy machine?); going on: the force guard slows the moves")

    # -- what the scenario's steps use (runtime.suite_interface.SuiteClient) --------------------------------
    def send_move(self, pose) -> None:
        """Send the move_to_pose goal to ``pose`` and wait until it was taken (``SuiteGoals.send_move``)."""
        self.goals.send_move(pose)

    def move_result(self) -> MoveResult | None:
        """The latest move goal's result, None while it runs (or before any)."""
        return self.goals.move_result()


    def follow_poses(self, on: bool) -> None:
        """Subscribe to the 500 Hz ground truth (ground_truth/platform_pose) and the controller's pose estimates
        (platform/pose_estimate) while a move settles (``on``), or stop: the runner must not load the machine."""
        if on and not self._pose_subs:
            for topic in FOLLOWED_POSES:
                self._raw_poses.pop(topic, None)
                self._decoded[topic] = (None, None)
                self._pose_subs.append(self.node.create_subscription(  # the ignore: as readiness_subs'
                    PoseStamped, topic, lambda data, t=topic: self._raw_poses.__setitem__(t, data),  # type: ignore[misc]
                    1, raw=True))
        elif not on and self._pose_subs:
            for sub in self._pose_subs:
                self.node.destroy_subscription(sub)
            self._pose_subs = []

    def _followed_pose(self, topic: str) -> np.ndarray | None:
        """The newest well-formed pose (6,) of a followed topic, decoded when asked; a malformed newest one is
        counted and the last good one kept; None before one (or when not followed)."""
        data = self._raw_poses.get(topic)
        if data is not None and data is not self._decoded[topic][0]:
            pose = self.malformed.read(topic, lambda d: pose_from_cdr(d, FOLLOWED_POSES[topic]), data)
            self._decoded[topic] = (data, pose[1] if pose is not None else self._decoded[topic][1])
        return self._decoded[topic][1] if data is not None else None

    def ground_truth(self) -> np.ndarray | None:
        """The newest ground-truth pose (6,) while followed (``follow_poses``)."""
        return self._followed_pose("ground_truth/platform_pose")

    def pose_estimate(self) -> np.ndarray | None:
        """Kinematics' newest pose estimate (6,) while followed (``follow_poses``)."""
        return self._followed_pose("platform/pose_estimate")

    def guard_status(self) -> GuardStatus | None:
        return self._guard

    def start_vibration(self, vibration: dict) -> VibrationStart:
        """Send the vibrate goal of ``vibration`` and wait for its plan or refusal (``SuiteGoals``)."""
        return self.goals.start_vibration(vibration)

    def identify_units(self, frequencies_hz, output_path: str, timeout_s: float) -> IdentificationEnd:
        """Run the planner's identify_vibration_units here and wait for its result (``SuiteGoals``)."""
        return self.goals.identify_units(frequencies_hz, output_path, timeout_s)

    def vibration_result(self) -> VibrationEnd | None:
        """The latest vibrate goal's result, None while it runs (or before any)."""
        return self.goals.vibration_result()

    def vibration_goal_open(self) -> bool:
        """Whether the latest vibrate goal was accepted and its result has not come (pending or running)."""
        return self.goals.vibration_goal_open()

    def stop_vibration(self) -> bool:
        """Cancel the latest vibrate goal if it is open; whether a cancel was sent (``SuiteGoals``)."""
        return self.goals.stop_vibration()


    # -- the end --------------------------------------------------------------------------------------------
    def stop_recorder(self, progress):
        """Ask the recorder to finish its file; the file's path, or None (SIGINT finishes it then)."""
        try:
            res = self.call(StopRecording, "mcap_recorder/stop", StopRecording.Request(), timeout=10.0)
        except (TimeoutError, RuntimeError, StepFailed) as exc:
            progress(f"recorder stop service failed ({exc}); SIGINT finishes the file")
            return None
        name = outcome_name(res.outcome.code)
        progress(f"recorder: {name}: {res.outcome.message} ({res.messages} messages, {res.bytes:,} bytes)")
        return res.path if name == "SUCCEEDED" else None

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()
