"""vibration planner node: a platform vibration -> self-contained vib_* command windows.

Topics (relative): sub platform/pose_estimate (PoseStamped, base), vibration/status
(DiagnosticStatus from the hardware emulator: what the units really do; a malformed one is counted on
/diagnostics and ignored, see messages.status_values); pub
vibration/joint_trajectory (JointTrajectory vib_1..vib_6: positions m,
velocities m/s, accelerations m/s^2; header.stamp = the vibration's common
start time t0, time_from_start relative to t0). Services vibration_planner/start
and vibration_planner/stop (std_srvs/Trigger). Diagnostics on /diagnostics.

The windows and their timing are vibration.streaming (pure): a finite vibration
that fits ``max_lookahead_s`` is sent whole in its first window; otherwise every
``window_period_s`` a window with ``lookahead_s`` of vibration and a ramp-out
tail, so if no later window arrives the units ramp out smoothly on their own.

States: idle, running, stopping, aborted (with the reason). start works from
idle or aborted: it needs a recent pose estimate (pose_timeout_s) and, when the
emulator's status is known, no latched e-stop and, if the status is recent
(STATUS_STALE_S; older means this process was held up), units at rest
(otherwise it says why; on a stale status the emulator's own window check rules).
t0 = start call (sim clock, at least the fresh pose estimate's stamp) + start_lead_s
(wall seconds: scaled to sim seconds by the sim clock's rate when it runs faster than real time). The planner
aborts -- stops streaming, says why on /diagnostics (ERROR for an e-stop, WARN
otherwise) and in its state -- when the emulator refuses one of its windows,
e-stops, reports the units stopped or idle before the planned end, or when it
was itself held up past the buffered look-ahead (the units have begun their
ramp-out; judged on the first tick after the stall by the wall clock at the measured sim rate,
since the sim clock is stale until the /clock sent meanwhile is taken). The start
answer carries the settings that run as JSON after "settings: " (the run summary
judges against those).
"""

from __future__ import annotations

import json
import time
from typing import cast

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.msg import ParameterDescriptor, ParameterType, SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from ..errors import MalformedMessageError, StewartError
from ..kinematics.robot_config import load_robot
from ..messages import cdr
from ..messages.stamped import pose_from_cdr
from ..messages.status_values import vibration_report_from_cdr
from ..runtime.sim_clock import ClockRate
from ..vibration.settings import (
    DEFAULT_DIRECTION,
    DEFAULT_FRAME,
    SETTINGS,
    parameters,
    settings_reason,
    start_check,
    start_refusal,
)
from ..vibration.streaming import StreamInterrupted, VibrationStream
from ..vibration.waveform import acceleration_from_displacement
from .common import (
    ERROR,
    OK,
    VIB_NAMES,
    WARN,
    Diagnostics,
    MalformedInputs,
    declare_float,
    float_param,
    reject,
    run_node,
    text_param,
)

POLL_PERIOD_S = 0.01  # wall-clock polling of the sim clock for the streaming
STALL_S = 0.1  # a tick this late means the process was held up: skip it (the sim clock is stale)
STATUS_STALE_S = 2.5  # wall s: the emulator repeats its status every second, so an older one is stale
STATUS_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
BUSY_STATES = ("pending", "ramping_in", "running", "ramping_out")


class VibrationPlannerNode(Node):
    """Thin adapter over stewart_vibration.vibration (decompose_vibration, VibrationStream)."""

    def __init__(self):
        super().__init__("vibration_planner")
        self.declare_parameter("robot_config", "", text_param("robot YAML path ('' = config/robot.yaml)", True))
        self.robot = load_robot(self.get_parameter("robot_config").value or None)
        self.declare_parameter("direction", list(DEFAULT_DIRECTION), ParameterDescriptor(
            type=ParameterType.PARAMETER_DOUBLE_ARRAY,
            description="vibration direction (3 values, any non-zero length) in `frame`"))
        self.declare_parameter("frame", DEFAULT_FRAME, text_param("frame of `direction`: platform | base"))
        for name, spec in parameters(self.robot).items():
            declare_float(self, name, spec.default, float_param(spec.description, spec.low, spec.high))
        self.add_on_set_parameters_callback(self.on_set_parameters)
        reason = settings_reason(self.robot, self.settings())
        if reason:
            raise ValueError(f"invalid initial parameters: {reason}")

        self.diagnostics = Diagnostics(self, "vibration planner")
        self.malformed = MalformedInputs(self, self.diagnostics)
        self.state = "idle"
        self.last_error = ""
        self.plan = None
        self.stream: VibrationStream | None = None
        self.run = None  # dict: settings, t0 (s), next_send (s), seen (s from t0: the last tick's sim time)
        self.pose_data = None  # raw PoseStamped bytes and their receive time (monotonic wall clock, s:
        # the sim clock may be stale when this process resumes from a stall)
        self.emulator = None  # latest VibrationReport from vibration/status
        self.emulator_received = 0.0  # when it arrived (monotonic wall clock, s)
        self.seen_event = 0
        self._pose_seen = 0
        self._last_tick = time.monotonic()
        # leads are wall-clock margins (a window must reach the emulator in time): faster than real time
        # they are scaled to as many more sim seconds
        self.clock_rate = ClockRate()
        self._last_rate_sample = 0.0
        self.pub = self.create_publisher(JointTrajectory, "vibration/joint_trajectory", 10)
        self.create_subscription(PoseStamped, "platform/pose_estimate", self.on_pose, 10, raw=True)
        self.create_subscription(DiagnosticStatus, "vibration/status", self.on_status, STATUS_QOS, raw=True)
        self.create_service(Trigger, "vibration_planner/start", self.on_start)
        self.create_service(Trigger, "vibration_planner/stop", self.on_stop)
        self.create_timer(POLL_PERIOD_S, self.tick, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.diagnostics.watch("platform/pose_estimate", 1.0, "from kinematics")
        self.diagnostics.watch("vibration/status", 3.0, "from hardware_emulator")
        self._report(OK, "idle")
        self.get_logger().info(f"vibration planner ready (robot {self.robot.source})")

    # -- parameters -----------------------------------------------------------------
    def settings(self) -> dict:
        return {name: self.get_parameter(name).value for name in SETTINGS}

    def on_set_parameters(self, params) -> SetParametersResult:
        s = self.settings()
        for p in params:
            if p.name in s:
                s[p.name] = p.value
        try:
            reason = settings_reason(self.robot, s)
        except (TypeError, ValueError) as exc:
            reason = f"invalid parameter value: {exc}"
        if reason:
            if hasattr(self, "diagnostics"):
                reject(self, self.diagnostics, "parameters", reason)
            return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    # -- inputs ------------------------------------------------------------------------
    def now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def on_pose(self, data: bytes) -> None:
        """Keep the latest estimate (500 Hz: decoded only when a vibration starts)."""
        self.pose_data = (data, time.monotonic())
        self._pose_seen += 1
        if self._pose_seen % 50 == 1:  # the freshness watch needs no more than a few per second
            self.diagnostics.seen("platform/pose_estimate")

    def on_status(self, data: bytes) -> None:
        """The emulator's vibration/status (raw). A malformed one is counted and ignored: the planner keeps the
        last good report (it neither believes the units run nor aborts for it)."""
        report = self.malformed.read("vibration/status", vibration_report_from_cdr, data)
        if report is None:
            return
        self.diagnostics.seen("vibration/status")
        self.emulator = report
        self.emulator_received = time.monotonic()
        if self.state not in ("running", "stopping"):
            self.seen_event = report.event_seq
            return
        t0 = self.run["t0"]
        new_event = report.event_seq != self.seen_event
        self.seen_event = report.event_seq
        if new_event and report.event.startswith("refused") and report.event_stamp is not None \
                and abs(report.event_stamp - t0) < 1e-6:
            self.abort(f"the hardware emulator refused a window of this vibration ({report.event})", WARN)
        elif report.state == "estopped":
            self.abort("emergency stop on the hardware emulator (call hardware_emulator/reset)", ERROR)
        elif report.state == "stopped" and report.since >= t0:
            self.abort(f"the vibration units stopped: {report.reason}", WARN)
        elif report.state == "idle" and report.since > t0:
            end = cast(VibrationStream, self.stream).planned_end  # running or stopping: a stream is set
            if self.state == "running" and (end is None or report.since < t0 + end - 0.05):
                self.abort(f"the vibration units went idle at {report.since:.3f} s, before the planned end "
                           f"({'until stop' if end is None else f'{t0 + end:.3f} s'}): {report.reason}", WARN)

    # -- state ---------------------------------------------------------------------------
    def _report(self, level, message: str) -> None:
        run = self.run or {}
        self.diagnostics.set(level, message, state=self.state, last_error=self.last_error or "none",
                             windows_sent=self.stream.windows_sent if self.stream else 0,
                             t0_s=f"{run['t0']:.6f}" if run else "")

    def abort(self, reason: str, level) -> None:
        """Stop streaming; state 'aborted: reason' until the next start."""
        self.state = f"aborted: {reason}"
        self.last_error = reason
        self.run = None
        self.get_logger().error(f"vibration aborted: {reason}") if level == ERROR else \
            self.get_logger().warning(f"vibration aborted: {reason}")
        self._report(level, self.state)

    def _refuse(self, response, reason: str):
        self.last_error = reason
        response.success, response.message = False, reason
        reject(self, self.diagnostics, "start", reason)
        return response

    # -- services --------------------------------------------------------------------------
    def on_start(self, request, response):
        if self.state in ("running", "stopping"):
            return self._refuse(response, f"already {self.state}; call stop first")
        emulator = self.emulator
        if emulator is not None and emulator.state == "estopped":
            return self._refuse(response, "emergency stop latched on the hardware emulator: call "
                                          "hardware_emulator/reset first")
        status_age = time.monotonic() - self.emulator_received
        if emulator is not None and emulator.state in BUSY_STATES and status_age <= STATUS_STALE_S:
            return self._refuse(response, f"the vibration units are not at rest ({emulator.message}); start again "
                                          f"when they are")
        if self.pose_data is None:
            return self._refuse(response, "no platform/pose_estimate received yet")
        now = self.now_s()
        if now <= 0:
            return self._refuse(response, "clock not running (use_sim_time without /clock?)")
        s = self.settings()
        data, received = self.pose_data
        age = time.monotonic() - received
        if age > s["pose_timeout_s"]:
            return self._refuse(response, f"pose estimate is {age:.3f} s old (wall time; pose_timeout_s "
                                          f"{s['pose_timeout_s']})")
        try:
            pose_stamp, pose = pose_from_cdr(data, "pose estimate")
        except MalformedMessageError as exc:
            self.malformed.refuse("platform/pose_estimate", exc)
            return self._refuse(response, f"pose estimate unusable: {exc}")
        # just resumed from a stall, this process may not have taken the latest /clock yet: the
        # fresh pose estimate's stamp (sim time) bounds the present from below
        now = max(now, pose_stamp)
        try:
            started = start_check(self.robot, pose, s, self.clock_rate.wall_margin)  # wall s -> sim s
        except StewartError as exc:
            return self._refuse(response, start_refusal(exc, s))
        plan, stream, first = started.plan, started.stream, started.first
        t0 = now + started.start_lead
        duration = s["duration_s"] if s["duration_s"] > 0 else None
        self.plan, self.stream = plan, stream
        # seen: the last sim time (s from t0) a tick saw, from which a stall is judged
        self.run = {"settings": s, "t0": t0, "next_send": now + s["window_period_s"], "seen": now - t0}
        self.state, self.last_error = "running", ""
        self.seen_event = emulator.event_seq if emulator is not None else 0
        self.publish(first)
        acc_g = acceleration_from_displacement(plan.amplitude, plan.frequency)
        ran = dict(s, direction=list(s["direction"]), t0_s=t0, pose=pose.tolist())
        text = (
            f"started: {plan.frequency:g} Hz, platform amplitude {plan.amplitude * 1e6:.3f} um ({acc_g:.3f} g) "
            f"along {np.round(plan.direction, 6).tolist()} (base frame), phase {plan.phase:.4f} rad, "
            f"t0 = {t0:.6f} s, ramp {s['ramp_s']} s, "
            f"duration {'until stop' if duration is None else str(duration) + ' s'}"
            f"{' (sent whole)' if stream.finished else ''}; "
            f"gains k = {np.round(plan.gains, 6).tolist()}; "
            f"leg amplitudes um = {np.round(plan.leg_amplitudes * 1e6, 3).tolist()}; "
            f"leg phases rad = {np.round(plan.leg_phases, 4).tolist()}"
            + ("; note: no vibration/status from the hardware emulator yet, so the units' state is unconfirmed"
               if emulator is None else
               f"; note: the last vibration/status is {status_age:.1f} s old (this process was held up?), so the "
               f"units' state is unconfirmed; the hardware emulator checks the window" if status_age > STATUS_STALE_S
               else "")
            + f"; settings: {json.dumps(ran)}"
        )
        self.get_logger().info(text)
        self.diagnostics.set(OK, "running", frequency_hz=plan.frequency, amplitude_um=plan.amplitude * 1e6,
                             gains=np.round(plan.gains, 6).tolist(),
                             leg_amplitudes_um=np.round(plan.leg_amplitudes * 1e6, 3).tolist())
        self._report(OK, "running")
        response.success, response.message = True, text
        return response

    def on_stop(self, request, response):
        if self.state not in ("running", "stopping"):
            response.success, response.message = True, f"already {self.state}"
            return response
        if self.state == "stopping":
            response.success, response.message = True, "already stopping"
            return response
        t0 = self.run["t0"]
        window = self.stream.stop_window(self.now_s() - t0)
        self.state = "stopping"
        if window is None:
            message = f"the vibration already ends at {t0 + self.stream.rest_at:.4f} s; letting it ramp out"
        else:
            self.publish(window)
            message = (f"stopping: ramp-out from {t0 + self.stream.stop_at:.4f} s over "
                       f"{self.run['settings']['ramp_s']} s, at rest at {t0 + window.rest_at:.4f} s")
        self._report(OK, "stopping")
        self.get_logger().info(message)
        response.success, response.message = True, message
        return response

    # -- streaming ---------------------------------------------------------------------------
    def tick(self) -> None:
        wall = time.monotonic()
        gap, self._last_tick = wall - self._last_tick, wall
        if gap <= STALL_S and wall - self._last_rate_sample >= 0.05:
            self._last_rate_sample = wall
            self.clock_rate.add(wall, self.now_s())
        run = self.run
        if run is None:
            return
        if gap > STALL_S:
            # this process was held up (SIGSTOP, a busy machine): the sim clock it sees is stale until the
            # /clock sent meanwhile is taken, which may not be soon. Judge by the wall clock now (at the
            # measured sim rate) whether the units ran out of commands; the next ticks judge by the sim clock
            self.get_logger().warning(f"the planner was held up {gap:.3f} s (wall clock)")
            try:
                cast(VibrationStream, self.stream).check_stall(run["seen"], gap * self.clock_rate.rate())
            except StreamInterrupted as exc:
                self.abort(str(exc), WARN)
            return
        now = self.now_s()
        rel = run["seen"] = now - run["t0"]
        # a run has its stream (both set by start)
        end = cast(VibrationStream, self.stream).planned_end if self.state == "running" else \
            cast(VibrationStream, self.stream).rest_at
        if cast(VibrationStream, self.stream).finished and end is not None and rel >= end:
            self.state, self.run = "idle", None
            self._report(OK, "idle")
            return
        if cast(VibrationStream, self.stream).finished or now < run["next_send"]:
            return
        run["next_send"] = now + run["settings"]["window_period_s"]
        try:
            window = cast(VibrationStream, self.stream).next_window(rel)
        except StreamInterrupted as exc:
            self.abort(str(exc), WARN)
            return
        if window is not None:
            self.publish(window)

    def publish(self, window) -> None:
        started = time.perf_counter()
        self.pub.publish(cdr.encode_joint_trajectory(VIB_NAMES, self.run["t0"], window.times, window.position,
                                                     window.velocity, window.acceleration))
        self.diagnostics.values.update(windows_sent=str(cast(VibrationStream, self.stream).windows_sent),
                                       last_window_points=str(len(window.times)),
                                       last_window_encode_ms=f"{(time.perf_counter() - started) * 1e3:.2f}")


def main(args=None) -> int:
    """Run the vibration planner node until SIGINT / SIGTERM; returns the exit code (2: it cannot start)."""
    return run_node(VibrationPlannerNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
