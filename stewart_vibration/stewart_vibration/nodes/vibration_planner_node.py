"""vibration planner node: a vibration session (action) -> self-contained vib_* command windows.

Action vibration_planner/vibrate (stewart_vibration_interfaces/action/Vibrate): the goal carries the
vibration (direction and frame, amplitude or acceleration, frequency, phase, duration, ramp); the node's
parameters are only the streaming's timing (lookahead_s, window_period_s, sample_period_s, lead_s,
start_lead_s, max_lookahead_s, pose_timeout_s). Feedback at 10 Hz: the units' state, the plan, the time
since t0 and what the sensors show delivered (analysis.delivered_from_poses). Result: the outcome (a code of
the one table), the plan, the active time and the cycles delivered. Cancel = a ramp-out over ramp_s. One
vibration at a time: a goal while one runs ends at once with BUSY. Action
vibration_planner/identify_vibration_units: the units' identification, written to a file the planner then plans
with (nodes.identification_server).

Topics (relative): sub platform/pose_estimate (PoseStamped, base; while a vibration runs its last 128 are kept
for the delivered figures), vibration/status (VibrationUnitsStatus from the hardware emulator: what the units
really do; a malformed one is counted on /diagnostics and ignored, see messages.status_values), platform/imu
and legs/joint_states (only while a closed loop or an identification needs them); pub
vibration/joint_trajectory (JointTrajectory vib_1..vib_6: positions m, velocities m/s, accelerations m/s^2;
header.stamp = the vibration's common start time t0, time_from_start relative to t0). Diagnostics on
/diagnostics.

States: idle, running, stopping, identifying, aborted (with the reason). A goal starts when
vibration.start_gate allows it and the settings pass vibration.settings.start_check; otherwise it ends at once
with the refusal's outcome. t0 = the goal's arrival (sim clock, at least the fresh pose estimate's stamp) +
start_lead_s (wall seconds: scaled to sim seconds by the sim clock's rate when it runs faster than real time).
The windows are vibration.streaming's; a vibration's ticks, stop and end vibration.delivery_run's, whose
docstring names every outcome that aborts it. An abort stops streaming and says why on /diagnostics (ERROR for
an e-stop, WARN otherwise), in the state and in the goal's outcome. A stall is judged on the first tick after it
by the wall clock at the measured sim rate: the sim clock is stale until the /clock sent meanwhile is taken.
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
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from sensor_msgs.msg import Imu, JointState
from trajectory_msgs.msg import JointTrajectory

from stewart_vibration_interfaces.action import Vibrate
from stewart_vibration_interfaces.msg import VibrationUnitsStatus

from ..analysis.delivered_from_poses import delivered_from_poses
from ..errors import MalformedMessageError, RefusedError, StewartError
from ..kinematics.robot_config import load_robot
from ..messages.joint_states import JointStateDecoder
from ..messages.joint_trajectory import encode_joint_trajectory
from ..messages.stamped import pose_from_cdr, poses_from_cdr
from ..messages.stamped_doubles import decode_imu
from ..messages.status_values import vibration_report_from_cdr
from ..parameters.tables import VIBRATION_PLANNER
from ..robot import VIB_NAMES
from ..runtime.sim_clock import ClockRate
from ..vibration.delivery_run import DeliveryRun, DeliveryStep, LoopSettings, RunEnd, start_delivery
from ..vibration.planner_parameters import parameter_change
from ..vibration.settings import STREAM_KEYS, default_settings, settings_reason, start_refusal
from ..vibration.start_gate import check_can_start
from ..vibration.streaming import VibrationStream
from ..vibration.unit_identification import load_identification_option
from .diagnostics import ERROR, OK, WARN, Diagnostics, MalformedInputs, reject
from .identification_server import IdentificationServer
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
    """Thin adapter over vibration.delivery_run behind the vibrate action; the inputs, parameters and start gate
    the identify action (nodes.identification_server) shares."""

    def __init__(self):
        super().__init__("vibration_planner")
        declare_table(self, VIBRATION_PLANNER)
        self.robot = load_robot(self.get_parameter("robot_config").value or None)
        self.add_on_set_parameters_callback(self.on_set_parameters)
        self.add_post_set_parameters_callback(self.after_set_parameters)
        if reason := settings_reason(self.robot, self.settings_with({})):
            raise ValueError(f"invalid initial parameters: {reason}")
        self.identification = load_identification_option(self.get_parameter("identification_file").value)
        self._identification_read: tuple[str, object] = ("", None)  # (path, what it held) of the last set's check
        self.diagnostics = Diagnostics(self, "vibration planner")
        self.malformed = MalformedInputs(self, self.diagnostics)
        self.state, self.last_error = "idle", ""
        self.run: DeliveryRun | None = None  # the vibration being delivered
        self.stream: VibrationStream | None = None  # the latest vibration's: its windows stay counted
        self.goal, self.done, self.plan_msg = None, Future(), None  # the running goal, its end, its VibrationPlan
        # raw PoseStamped bytes and their receive time (monotonic wall s: the sim clock may be stale when this
        # process resumes from a stall); the latest VibrationReport and when it arrived (monotonic wall s)
        self.pose_data: tuple[bytes, float] | None = None
        self.recent_poses: deque = deque(maxlen=DELIVERED_WINDOW)  # raw, while a vibration runs
        self.emulator, self.emulator_received = None, 0.0
        self._pose_seen, self._last_tick, self._last_rate_sample = 0, time.monotonic(), 0.0
        # leads are wall-clock margins (a window must reach the emulator in time): faster than real time
        # they are scaled to as many more sim seconds
        self.clock_rate = ClockRate()
        self.pub = self.create_publisher(JointTrajectory, "vibration/joint_trajectory", 10)
        self.create_subscription(PoseStamped, "platform/pose_estimate", self.on_pose, 10, raw=True)
        self.create_subscription(VibrationUnitsStatus, "vibration/status", self.on_status, STATUS_QOS, raw=True)
        self._imu_subscription = self._joint_state_subscription = None  # 500 Hz: only while needed
        self._joint_states = JointStateDecoder()
        self.action = ActionServer(self, Vibrate, "vibration_planner/vibrate", execute_callback=self.execute,
                                   goal_callback=lambda goal: GoalResponse.ACCEPT, cancel_callback=self.on_cancel)
        self.identify = IdentificationServer(self)
        self.create_timer(POLL_PERIOD_S, self.tick, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.diagnostics.watch("platform/pose_estimate", 1.0, "from kinematics")
        self.diagnostics.watch("vibration/status", 3.0, "from hardware_emulator")
        self.report(OK, "idle")
        self.get_logger().info(f"vibration planner ready (robot {self.robot.source})")

    # -- parameters -----------------------------------------------------------------
    def settings_with(self, vibration: dict) -> dict:
        """Every setting: the streaming parameters, and ``vibration``'s keys over the defaults of the rest."""
        s = default_settings(self.robot)
        s.update({name: self.get_parameter(name).value for name in STREAM_KEYS})
        s.update(vibration)
        return s

    def on_set_parameters(self, params) -> SetParametersResult:
        reason, read = parameter_change(self.robot, self.settings_with({}), {p.name: p.value for p in params})
        if read is not None:  # after_set_parameters takes what was read
            self._identification_read = read
        if reason and hasattr(self, "diagnostics"):
            reject(self, self.diagnostics, "parameters", reason)
        return SetParametersResult(successful=not reason, reason=reason)

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
        run, ident = self.run, self.identify.runner
        if (ident is None and (run is None or not run.listens_to_imu)) or \
                (sample := self.malformed.read("platform/imu", decode_imu, data)) is None:
            return
        stamp, _, rate, accel = sample
        if ident is not None:
            ident.add_imu(stamp, accel, rate)
        elif reason := cast(DeliveryRun, run).add_imu(stamp, accel, rate):
            self._act(cast(DeliveryRun, run).delivery_limit(self.now_s(), reason))

    def on_joint_states(self, data: bytes) -> None:
        """The units' sensor readings for the identification run (else ignored)."""
        if (runner := self.identify.runner) is not None and \
                (state := self.malformed.read("legs/joint_states", self._joint_states.decode, data)) is not None:
            runner.add_unit_readings(state.stamp, state.names, state.position)

    def on_status(self, data: bytes) -> None:
        """The emulator's vibration/status (raw). A malformed one is counted and ignored: the planner keeps the
        last good report (it neither believes the units run nor aborts for it)."""
        if (report := self.malformed.read("vibration/status", vibration_report_from_cdr, data)) is None:
            return
        self.diagnostics.seen("vibration/status")
        self.emulator, self.emulator_received = report, time.monotonic()
        if (runner := self.identify.runner) is not None:
            runner.on_status(report)
            self.identify.settle(runner)
        elif self.run is not None and (end := self.run.on_status(report)) is not None:
            self._end(end)

    def subscribe_sensors(self, units: bool) -> None:
        """Subscribe platform/imu (and with ``units`` legs/joint_states) the first time a run needs them."""
        if self._imu_subscription is None:
            self._imu_subscription = self.create_subscription(Imu, "platform/imu", self.on_imu, IMU_QOS, raw=True)
            self.diagnostics.watch("platform/imu", 1.0, "from hardware_emulator (closed loop)")
        if units and self._joint_state_subscription is None:
            self._joint_state_subscription = self.create_subscription(JointState, "legs/joint_states",
                                                                      self.on_joint_states, IMU_QOS, raw=True)

    def unsubscribe_unit_sensors(self) -> None:
        if self._joint_state_subscription is not None:
            self.destroy_subscription(self._joint_state_subscription)
            self._joint_state_subscription = None

    def check_can_start(self, pose_timeout_s: float) -> float:
        """The clock now (s) if the robot may be driven now (start_gate.check_can_start); RefusedError if not."""
        emulator, now = self.emulator, self.now_s()
        pose_age = None if self.pose_data is None else time.monotonic() - self.pose_data[1]
        check_can_start(self.state, emulator.state if emulator else None,
                        time.monotonic() - self.emulator_received, STATUS_STALE_S,
                        emulator.time if emulator else None, now, pose_age, pose_timeout_s,
                        self.clock_rate.rate(), emulator.active if emulator else True)
        return now

    def refused(self, goal_handle, result, what: str, name: str, reason: str):
        """End a refused goal at once with ``name`` and ``reason`` in ``result``."""
        self.last_error = reason
        reject(self, self.diagnostics, what, reason)
        goal_handle.abort()
        result.outcome = outcome(name, reason)
        return result

    # -- the vibrate action -------------------------------------------------------------------
    async def execute(self, goal_handle):
        """One vibration session: refuse it with its outcome, or run it until it ends, is cancelled or aborts."""
        settings = self.settings_with(goal_settings(goal_handle.request))
        try:
            self._start(settings, goal_handle)
        except Exception as exc:  # noqa: BLE001 - every refusal (and a defect) ends the goal with its code
            if isinstance(exc, StewartError):
                name, reason = exc.outcome, str(exc) if isinstance(exc, RefusedError) else start_refusal(exc, settings)
            else:
                name, reason = "INTERNAL_ERROR", f"{type(exc).__name__}: {exc}"
                self.get_logger().error(f"vibrate goal failed: {reason}")
            return self.refused(goal_handle, Vibrate.Result(), "start", name, reason)
        plan = self.plan_msg  # this run's: another may have begun by the time its end is taken
        name, message, run = await self.done
        result = Vibrate.Result(plan=plan)
        result.outcome = outcome(name, message)
        result.active_s, result.cycles_delivered = run.delivered_dose()
        result.loop_corrections, result.demand_correction = run.loop_figures()
        end_goal(goal_handle, name)
        return result

    def _start(self, settings: dict, goal_handle) -> None:
        """Check and start the vibration of ``settings`` for ``goal_handle``; RefusedError / StewartError if not."""
        now = self.check_can_start(settings["pose_timeout_s"])
        try:
            pose_stamp, pose = pose_from_cdr(cast(tuple, self.pose_data)[0], "pose estimate")
        except MalformedMessageError as exc:
            self.malformed.refuse("platform/pose_estimate", exc)
            raise RefusedError("NOT_READY", f"pose estimate unusable: {exc}") from None
        loop = LoopSettings(self._float("loop_gain"), self._float("imu_average_s"), self._float("imu_silence_s")) \
            if self.get_parameter("closed_loop").value else None
        run, first, summary = start_delivery(self.robot, pose, pose_stamp, now, settings, self.clock_rate.wall_margin,
                                             self.emulator.event_seq if self.emulator is not None else 0,
                                             self.identification, loop)
        if run.loop is not None:
            self.subscribe_sensors(units=False)
        self.run, self.stream, self.goal, self.done = run, run.stream, goal_handle, Future()
        plan = run.stream.plan
        self.plan_msg = plan_message(plan, settings, run.t0)
        self.state, self.last_error = "running", ""
        self.publish(first)
        self.get_logger().info(summary)
        self.diagnostics.set(OK, "running", frequency_hz=plan.frequency, amplitude_um=plan.amplitude * 1e6,
                             gains=np.round(plan.gains, 6).tolist(),
                             leg_amplitudes_um=np.round(plan.leg_amplitudes * 1e6, 3).tolist())
        self.report(OK, "running")

    def on_cancel(self, goal_handle) -> CancelResponse:
        """Cancel = ramp out (the goal ends CANCELED when the units are at rest); a goal already ending is let be."""
        if self.run is not None and self.goal is goal_handle and self.state == "running":
            self._act(DeliveryStep(stop=self.run.stop(self.now_s())))
        return CancelResponse.ACCEPT

    def _feedback(self, run: DeliveryRun) -> None:
        """The goal's feedback: the units' state, the plan, the time since t0 and the delivered figures."""
        feedback = Vibrate.Feedback(plan=self.plan_msg, elapsed_s=self.now_s() - run.t0)
        feedback.state = UNIT_STATES.get(self.emulator.state if self.emulator else "idle", 0)
        poses = poses_from_cdr(list(self.recent_poses), "pose estimate")
        delivered = delivered_from_poses(self.robot, poses.stamps, poses.values, run.stream.plan)
        if delivered.known:
            feedback.frequency_hz, feedback.delivered_amplitude_m = delivered.frequency_hz, delivered.amplitude_m
            feedback.direction_error_rad, feedback.phase_spread_rad = (delivered.direction_error_rad,
                                                                       delivered.phase_spread_rad)
        feedback.loop_corrections, feedback.demand_correction = run.loop_figures()
        self.goal.publish_feedback(feedback)

    # -- streaming ---------------------------------------------------------------------------
    def tick(self) -> None:
        wall = time.monotonic()
        gap, self._last_tick = wall - self._last_tick, wall
        if gap <= STALL_S and wall - self._last_rate_sample >= 0.05:
            self._last_rate_sample = wall
            self.clock_rate.add(wall, self.now_s())
        if (runner := self.identify.runner) is not None:
            self.identify.tick(runner)
        elif self.run is not None and gap > STALL_S:  # held up (SIGSTOP, a busy machine): the sim clock is stale
            self.get_logger().warning(f"the planner was held up {gap:.3f} s (wall clock)")
            self._act(self.run.after_stall(gap * self.clock_rate.rate()))
        elif self.run is not None:
            self._act(self.run.tick(self.now_s(), wall))

    def _act(self, step: DeliveryStep) -> None:
        """Carry out a step of the running vibration, in DeliveryStep's order."""
        if step.feedback:
            self._feedback(cast(DeliveryRun, self.run))
        if step.stop is not None:
            self.state = "stopping"
            if step.stop.window is not None:
                self.publish(step.stop.window)
            self.report(OK, "stopping")
            self.get_logger().info(step.stop.message)
        if step.window is not None:
            self.publish(step.window)
        if step.end is not None:
            self._end(step.end)

    def publish(self, window) -> None:
        started = time.perf_counter()
        self.pub.publish(encode_joint_trajectory(VIB_NAMES, cast(DeliveryRun, self.run).t0, window.times,
                                                     window.position, window.velocity, window.acceleration))
        self.diagnostics.values.update(windows_sent=str(cast(VibrationStream, self.stream).windows_sent),
                                       last_window_points=str(len(window.times)),
                                       last_window_encode_ms=f"{(time.perf_counter() - started) * 1e3:.2f}")

    # -- state ---------------------------------------------------------------------------
    def report(self, level, message: str) -> None:
        self.diagnostics.set(level, message, state=self.state, last_error=self.last_error or "none",
                             windows_sent=self.stream.windows_sent if self.stream else 0,
                             t0_s=f"{self.run.t0:.6f}" if self.run else "")

    def _end(self, end: RunEnd) -> None:
        """End the running vibration: idle after it ran (or was cancelled), else aborted with the reason (its state
        until the next start)."""
        if end.aborted:
            self.state, self.last_error = f"aborted: {end.message}", end.message
        else:
            self.state = "idle"
        self._finish(end.outcome, end.message)
        if end.emergency:  # one severity per call site: rclpy refuses a call site whose severity changes
            self.get_logger().error(f"vibration aborted: {end.message}")
        elif end.aborted:
            self.get_logger().warning(f"vibration aborted: {end.message}")
        self.report(OK if not end.aborted else ERROR if end.emergency else WARN, self.state)

    def _finish(self, outcome_name: str, message: str) -> None:
        """End the running goal (its execute returns the result) and forget the run."""
        run, self.run = self.run, None
        self.recent_poses.clear()
        if run is not None and not self.done.done():
            run.ended = self.now_s()
            self.done.set_result((outcome_name, message, run))

    def shutdown(self) -> None:
        """A vibration still running ramps out (its goal ends SHUTDOWN): the units never keep a stale stream."""
        if self.run is not None and self.state == "running":
            self._act(DeliveryStep(stop=self.run.stop(self.now_s())))
        self._finish("SHUTDOWN", "the vibration planner is shutting down: the vibration ramps out")


def main(args=None) -> int:
    """Run the vibration planner node until SIGINT / SIGTERM; returns the exit code (2: it cannot start)."""
    return run_node(VibrationPlannerNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
