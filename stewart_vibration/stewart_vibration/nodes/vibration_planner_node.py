"""vibration planner node: a vibration session (action) -> self-contained vib_* command windows.

Action vibration_planner/vibrate (stewart_vibration_interfaces/action/Vibrate): the goal carries the
vibration (direction and frame, amplitude or acceleration, frequency, phase, duration, ramp); the node's
parameters are only the streaming's timing (lookahead_s, window_period_s, sample_period_s, lead_s,
start_lead_s, max_lookahead_s, pose_timeout_s). Feedback at 10 Hz: the units' state, the plan, the time
since t0 and what the sensors show delivered (frequency, amplitude along the direction, direction error,
the legs' phase spread; analysis.delivered_from_poses). Result: the outcome (a code of the one table), the plan,
the active time and the cycles delivered. Cancel = a ramp-out over ramp_s. One vibration at a time: a goal
while one runs ends at once with BUSY. Action vibration_planner/identify_vibration_units: the units'
identification (vibration.identification_runner), written to a file the planner then plans with.

Topics (relative): sub platform/pose_estimate (PoseStamped, base; while a vibration runs its last 128 are kept
for the delivered figures, the legs' phases from the lengths they imply), vibration/status (VibrationUnitsStatus
from the hardware emulator: what the units really do; a malformed one is counted on /diagnostics and ignored,
see messages.status_values); pub vibration/joint_trajectory (JointTrajectory vib_1..vib_6: positions m,
velocities m/s, accelerations m/s^2; header.stamp = the vibration's common start time t0, time_from_start
relative to t0). Diagnostics on /diagnostics.

The windows and their timing are vibration.streaming (pure); a vibration's start, ticks, stop and end are
vibration.delivery_run (its docstring names every outcome that aborts it).

States: idle, running, stopping, identifying, aborted (with the reason). A goal starts from idle or aborted
when vibration.start_gate allows it (no vibration running, no latched e-stop, units at rest by a recent
status, the planner's clock running and the robot's, a recent pose estimate) and the settings pass
vibration.settings.start_check; otherwise it ends at once with the refusal's outcome.
t0 = the goal's arrival (sim clock, at least the fresh pose estimate's stamp) + start_lead_s
(wall seconds: scaled to sim seconds by the sim clock's rate when it runs faster than real time). An abort
stops streaming and says why on /diagnostics (ERROR for an e-stop, WARN otherwise), in the planner's state and
in the goal's outcome. A stall past the buffered look-ahead is judged on the first tick after it by the wall
clock at the measured sim rate, since the sim clock is stale until the /clock sent meanwhile is taken.
"""

from __future__ import annotations

import time
from collections import deque
from typing import cast

import numpy as np
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from sensor_msgs.msg import Imu, JointState
from trajectory_msgs.msg import JointTrajectory

from stewart_vibration_interfaces.action import IdentifyVibrationUnits, Vibrate
from stewart_vibration_interfaces.msg import VibrationUnitsStatus

from ..analysis.delivered_from_poses import delivered_from_poses
from ..errors import MalformedMessageError, RefusedError, StewartError
from ..kinematics.robot_config import load_robot
from ..messages import cdr
from ..messages.stamped import pose_from_cdr, poses_from_cdr
from ..messages.status_values import vibration_report_from_cdr
from ..output_files import writable_output
from ..parameters.tables import VIBRATION_PLANNER
from ..robot import VIB_NAMES
from ..runtime.sim_clock import ClockRate
from ..vibration.delivery_run import DeliveryRun, DeliveryStep, LoopSettings, RunEnd, Stop, start_delivery
from ..vibration.identification_runner import IdentificationRunner
from ..vibration.identification_session import identification_steps
from ..vibration.settings import STREAM_KEYS, default_settings, settings_reason, start_refusal
from ..vibration.start_gate import check_can_start
from ..vibration.streaming import VibrationStream
from ..vibration.unit_identification import FILE_KIND, load_identification_option
from .diagnostics import ERROR, OK, WARN, Diagnostics, MalformedInputs, reject
from .node_parameters import declare_table
from .outcomes import end_goal, outcome
from .run_loop import STATUS_QOS, run_node
from .vibration_goal import UNIT_STATES, goal_settings, plan_message

POLL_PERIOD_S = 0.01  # wall-clock polling of the sim clock for the streaming
STALL_S = 0.1  # a tick this late means the process was held up: skip it (the sim clock is stale)
STATUS_STALE_S = 2.5  # wall s: the emulator repeats its status every second, so an older one is stale
IMU_QOS = QoSProfile(depth=500, reliability=ReliabilityPolicy.RELIABLE)  # 1 s of samples: bursts of 10 every 20 ms
DELIVERED_WINDOW = 128  # the last samples (~0.25 s at 500 Hz) the delivered figures are judged over


class VibrationPlannerNode(Node):
    """Thin adapter over vibration.delivery_run and vibration.identification_runner behind the two actions."""

    def __init__(self):
        super().__init__("vibration_planner")
        declare_table(self, VIBRATION_PLANNER)
        self.robot = load_robot(self.get_parameter("robot_config").value or None)
        self.add_on_set_parameters_callback(self.on_set_parameters)
        self.add_post_set_parameters_callback(self.after_set_parameters)
        reason = settings_reason(self.robot, self.settings_with({}))
        if reason:
            raise ValueError(f"invalid initial parameters: {reason}")
        self.identification = load_identification_option(self.get_parameter("identification_file").value)
        self._identification_read: tuple[str, object] = ("", None)  # (path, what it held) of the last set's check

        self.diagnostics = Diagnostics(self, "vibration planner")
        self.malformed = MalformedInputs(self, self.diagnostics)
        self.state = "idle"
        self.last_error = ""
        self.run: DeliveryRun | None = None  # the vibration being delivered
        self.stream: VibrationStream | None = None  # the latest vibration's (its windows stay counted)
        self.identifying: IdentificationRunner | None = None
        self.goal = None  # the running goal's handle (a vibration's or an identification's)
        self.done = Future()  # its end, which the goal's execute awaits
        self.plan_msg = None  # the running vibration's VibrationPlan
        self.pose_data = None  # raw PoseStamped bytes and their receive time (monotonic wall clock, s:
        # the sim clock may be stale when this process resumes from a stall)
        self.recent_poses: deque = deque(maxlen=DELIVERED_WINDOW)  # raw, while a vibration runs
        self.emulator = None  # latest VibrationReport from vibration/status
        self.emulator_received = 0.0  # when it arrived (monotonic wall clock, s)
        self._pose_seen = 0
        self._last_tick = time.monotonic()
        # leads are wall-clock margins (a window must reach the emulator in time): faster than real time
        # they are scaled to as many more sim seconds
        self.clock_rate = ClockRate()
        self._last_rate_sample = 0.0
        self.pub = self.create_publisher(JointTrajectory, "vibration/joint_trajectory", 10)
        self.create_subscription(PoseStamped, "platform/pose_estimate", self.on_pose, 10, raw=True)
        self.create_subscription(VibrationUnitsStatus, "vibration/status", self.on_status, STATUS_QOS, raw=True)
        self.action = ActionServer(self, Vibrate, "vibration_planner/vibrate", execute_callback=self.execute,
                                   goal_callback=lambda goal: GoalResponse.ACCEPT, cancel_callback=self.on_cancel)
        self._imu_subscription = None
        self._joint_state_subscription = None
        self._joint_states = cdr.JointStateDecoder()
        self.identify_action = ActionServer(
            self, IdentifyVibrationUnits, "vibration_planner/identify_vibration_units",
            execute_callback=self.identify_execute, goal_callback=lambda goal: GoalResponse.ACCEPT,
            cancel_callback=lambda goal: CancelResponse.ACCEPT)
        self.create_timer(POLL_PERIOD_S, self.tick, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.diagnostics.watch("platform/pose_estimate", 1.0, "from kinematics")
        self.diagnostics.watch("vibration/status", 3.0, "from hardware_emulator")
        self._report(OK, "idle")
        self.get_logger().info(f"vibration planner ready (robot {self.robot.source})")

    # -- parameters -----------------------------------------------------------------
    def settings_with(self, vibration: dict) -> dict:
        """Every setting: the streaming parameters, and ``vibration``'s keys over the defaults of the rest."""
        s = default_settings(self.robot)
        s.update({name: self.get_parameter(name).value for name in STREAM_KEYS})
        s.update(vibration)
        return s

    def on_set_parameters(self, params) -> SetParametersResult:
        s = self.settings_with({})
        for p in params:
            if p.name in s:
                s[p.name] = p.value
        try:
            reason = settings_reason(self.robot, s)
        except (TypeError, ValueError) as exc:
            reason = f"invalid parameter value: {exc}"
        for p in params:
            if p.name == "identification_file" and not reason:
                try:  # read once here; after_set_parameters takes what was read
                    self._identification_read = (p.value, load_identification_option(p.value))
                except StewartError as exc:
                    reason = f"identification_file: {exc}"
        if reason:
            if hasattr(self, "diagnostics"):
                reject(self, self.diagnostics, "parameters", reason)
            return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def after_set_parameters(self, params) -> None:
        """A new identification_file (already checked) is loaded for the next vibration."""
        for p in params:
            if p.name == "identification_file":
                path, read = self._identification_read
                self.identification = read if path == p.value else load_identification_option(p.value)
                self.get_logger().info(f"identification: {p.value or 'none (uncompensated)'}")

    def _float(self, name: str) -> float:
        return float(self.get_parameter(name).value)

    # -- inputs ------------------------------------------------------------------------
    def now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def on_pose(self, data: bytes) -> None:
        """Keep the latest estimate (500 Hz: decoded only when a vibration starts or feedback is due)."""
        self.pose_data = (data, time.monotonic())
        if self.run is not None:
            self.recent_poses.append(data)
        self._pose_seen += 1
        if self._pose_seen % 50 == 1:  # the freshness watch needs no more than a few per second
            self.diagnostics.seen("platform/pose_estimate")

    def on_imu(self, data: bytes) -> None:
        """A platform IMU sample for the identification or the running vibration's closed loop (else ignored)."""
        run, ident = self.run, self.identifying
        if ident is None and (run is None or not run.listens_to_imu or self.state != "running"):
            return
        sample = self.malformed.read("platform/imu", cdr.decode_imu, data)
        if sample is None:
            return
        stamp, _, rate, accel = sample
        if ident is not None:
            ident.add_imu(stamp, accel, rate)
        elif reason := cast(DeliveryRun, run).add_imu(stamp, accel, rate):
            self._act(cast(DeliveryRun, run).delivery_limit(self.now_s(), reason))

    def on_joint_states(self, data: bytes) -> None:
        """The units' sensor readings for the identification run (else ignored)."""
        if self.identifying is not None:
            state = self.malformed.read("legs/joint_states", self._joint_states.decode, data)
            if state is not None:
                self.identifying.add_unit_readings(state.stamp, state.names, state.position)

    def on_status(self, data: bytes) -> None:
        """The emulator's vibration/status (raw). A malformed one is counted and ignored: the planner keeps the
        last good report (it neither believes the units run nor aborts for it)."""
        report = self.malformed.read("vibration/status", vibration_report_from_cdr, data)
        if report is None:
            return
        self.diagnostics.seen("vibration/status")
        self.emulator, self.emulator_received = report, time.monotonic()
        if self.identifying is not None:
            self.identifying.on_status(report)
            self._settle_identification(self.identifying)
        elif self.run is not None and (end := self.run.on_status(report)) is not None:
            self._end(end)

    # -- the identification action -----------------------------------------------------
    async def identify_execute(self, goal_handle):
        """The identification run (IdentifyVibrationUnits): refuse it with its outcome, or run it to its end."""
        result = IdentifyVibrationUnits.Result()
        try:
            self._start_identification(goal_handle)
        except StewartError as exc:
            self.last_error = str(exc)
            reject(self, self.diagnostics, "identify", str(exc))
            goal_handle.abort()
            result.outcome = outcome(exc.outcome, str(exc))
            return result
        end = await self.done
        self.identifying, self.state = None, "idle"
        if self._joint_state_subscription is not None:  # 500 Hz the planner needs only while identifying
            self.destroy_subscription(self._joint_state_subscription)
            self._joint_state_subscription = None
        result.outcome, result.path, result.problems = outcome(end.outcome, end.message), end.path, end.problems
        result.duration_s = end.duration_s
        end_goal(goal_handle, end.outcome)
        self._report(OK, "idle")
        return result

    def _start_identification(self, goal_handle) -> None:
        """Check the goal, then that the run may start now, at the current pose, and start it; StewartError if
        not."""
        goal = goal_handle.request
        steps, amplitude = identification_steps(tuple(goal.frequencies_hz), float(goal.amplitude_m),
                                                self.robot.vibration_unit)
        path = writable_output(goal.output_path or f"vibration_identification_{time.strftime('%Y%m%d_%H%M%S')}.yaml",
                               "vibration identification", lambda tree: tree.get("kind") == FILE_KIND)
        s = self.settings_with({})
        now = self._check_can_start(s["pose_timeout_s"])
        _, pose = pose_from_cdr(cast(tuple, self.pose_data)[0], "pose estimate")
        self.identifying = IdentificationRunner.start(steps, amplitude, pose, now,
                                                      self.clock_rate.wall_margin(s["start_lead_s"]), path,
                                                      self.emulator.event_seq if self.emulator is not None else 0)
        self.state, self.goal, self.done = "identifying", goal_handle, Future()
        self._ensure_imu_subscription()
        if self._joint_state_subscription is None:
            self._joint_state_subscription = self.create_subscription(JointState, "legs/joint_states",
                                                                      self.on_joint_states, IMU_QOS, raw=True)
        self.get_logger().info(self.identifying.summary)
        self._report(OK, "identifying")

    def _identification_tick(self, ident: IdentificationRunner) -> None:
        """Send the steps' windows when due, the feedback at 10 Hz, and conclude after the last step."""
        step = ident.tick(self.now_s(), time.monotonic(), self.goal.is_cancel_requested, self.emulator)
        for stamp, times, position, velocity, acceleration in step.windows:
            self.pub.publish(cdr.encode_joint_trajectory(VIB_NAMES, stamp, times, position, velocity, acceleration))
        if step.progress is not None:
            number, steps, unit, frequency = step.progress
            self.goal.publish_feedback(IdentifyVibrationUnits.Feedback(step=number, steps=steps, unit=unit,
                                                                       frequency_hz=frequency))
        if step.ready:
            ident.conclude(self.robot.gravity, self._float("imu_average_s"), self._float("unit_sensor_latency_s"))
        self._settle_identification(ident)

    def _settle_identification(self, ident: IdentificationRunner) -> None:
        """Once the run has ended, its goal's execute gets the end (a written file is planned with next)."""
        if ident.end is None or self.done.done():
            return
        if ident.end.outcome == "SUCCEEDED":
            self.set_parameters([Parameter("identification_file", value=ident.end.path)])
        self.done.set_result(ident.end)
