"""vibration planner node: a platform vibration -> self-contained vib_* command windows.

Topics (relative): sub platform/pose_estimate (PoseStamped), vibration/status
(DiagnosticStatus from the hardware emulator: what the units really do); pub
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
ramp-out). The start answer carries the settings that run as JSON after
"settings: " (the run summary judges against those).
"""

from __future__ import annotations

import json
import math
import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.msg import ParameterDescriptor, ParameterType, SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from ..emulation.vibration_status import report_from_values
from ..errors import StewartError, VibrationLimitError
from ..messages import cdr
from ..robot import STANDARD_GRAVITY, load_robot
from ..rotations import pose_from_position_quaternion
from ..sim_clock import ClockRate
from ..vibration import decompose_vibration
from ..vibration.decompose import FRAMES
from ..vibration.feasibility import check_command_limits
from ..vibration.streaming import StreamInterrupted, StreamSettings, VibrationStream
from .common import (
    ERROR,
    OK,
    VIB_NAMES,
    WARN,
    Diagnostics,
    declare_float,
    float_param,
    reject,
    run_node,
    text_param,
)

MAX_WINDOW_SAMPLES = 100_000  # one message; the emulator refuses windows reaching > 30 s ahead anyway
POLL_PERIOD_S = 0.01  # wall-clock polling of the sim clock for the streaming
STALL_S = 0.1  # a tick this late means the process was held up: skip it (the sim clock is stale)
STATUS_STALE_S = 2.5  # wall s: the emulator repeats its status every second, so an older one is stale
STATUS_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
BUSY_STATES = ("pending", "ramping_in", "running", "ramping_out")
SETTINGS = ("direction", "frame", "amplitude_m", "acceleration_g", "frequency_hz", "phase_rad", "duration_s", "ramp_s",
            "lookahead_s", "window_period_s", "sample_period_s", "lead_s", "start_lead_s", "max_lookahead_s",
            "pose_timeout_s")


def check_settings(robot, s: dict) -> str | None:
    """The reason the planner settings ``s`` are invalid, or None."""
    unit = robot.vibration_unit
    direction = np.asarray(list(s["direction"]), dtype=float)
    if direction.shape != (3,) or not np.isfinite(direction).all() or np.linalg.norm(direction) < 1e-9:
        return f"direction must be 3 finite values, not all zero; got {list(s['direction'])}"
    if s["frame"] not in FRAMES:
        return f"frame must be one of {list(FRAMES)}, got {s['frame']!r}"
    for name, value in s.items():
        if name not in ("direction", "frame") and not math.isfinite(value):
            return f"{name} must be finite, got {value}"
    if not unit.frequency_min <= s["frequency_hz"] <= unit.frequency_max:
        return (f"frequency_hz {s['frequency_hz']} is outside the vibration unit's band "
                f"[{unit.frequency_min}, {unit.frequency_max}] Hz")
    for name in ("sample_period_s", "lookahead_s", "window_period_s", "max_lookahead_s", "pose_timeout_s"):
        if s[name] <= 0:
            return f"{name} must be > 0, got {s[name]}"
    for name in ("lead_s", "start_lead_s", "duration_s"):
        if s[name] < 0:
            return f"{name} must be >= 0, got {s[name]}"
    samples = (max(s["max_lookahead_s"], s["lookahead_s"] + s["ramp_s"]) + s["start_lead_s"]) / s["sample_period_s"]
    if samples > MAX_WINDOW_SAMPLES:
        return (f"a window could hold {samples:.0f} samples (max_lookahead_s / sample_period_s); at most "
                f"{MAX_WINDOW_SAMPLES}: raise sample_period_s or lower max_lookahead_s")
    if s["amplitude_m"] < 0:
        return f"amplitude_m must be >= 0, got {s['amplitude_m']}"
    if s["amplitude_m"] == 0 and s["acceleration_g"] <= 0:
        return "acceleration_g must be > 0 when amplitude_m = 0"
    if s["ramp_s"] <= 0:
        return f"ramp_s must be > 0, got {s['ramp_s']}"
    if s["duration_s"] != 0 and s["duration_s"] < 2 * s["ramp_s"]:
        return f"duration_s {s['duration_s']} must be 0 (until stop) or >= 2 ramp_s = {2 * s['ramp_s']}"
    if s["lookahead_s"] <= s["window_period_s"]:
        return (f"lookahead_s {s['lookahead_s']} must exceed window_period_s {s['window_period_s']} (the next "
                "window must arrive before the last one's ramp-out)")
    if s["start_lead_s"] < s["lead_s"]:
        return f"start_lead_s {s['start_lead_s']} must be >= lead_s {s['lead_s']} (the first window starts at t0)"
    if s["max_lookahead_s"] < s["lookahead_s"]:
        return f"max_lookahead_s {s['max_lookahead_s']} must be >= lookahead_s {s['lookahead_s']}"
    if s["sample_period_s"] * s["frequency_hz"] > 0.1:
        return (f"sample_period_s {s['sample_period_s']} is too coarse for {s['frequency_hz']} Hz "
                "(need >= 10 samples per period)")
    return None


class VibrationPlannerNode(Node):
    """Thin adapter over stewart_vibration.vibration (decompose_vibration, VibrationStream)."""

    def __init__(self):
        super().__init__("vibration_planner")
        self.declare_parameter("robot_config", "", text_param("robot YAML path ('' = config/robot.yaml)", True))
        self.robot = load_robot(self.get_parameter("robot_config").value or None)
        unit = self.robot.vibration_unit
        self.declare_parameter("direction", [0.0, 0.0, 1.0], ParameterDescriptor(
            type=ParameterType.PARAMETER_DOUBLE_ARRAY,
            description="vibration direction (3 values, any non-zero length) in `frame`"))
        self.declare_parameter("frame", "platform", text_param("frame of `direction`: platform | base"))
        number = [
            ("amplitude_m", 0.0, "platform displacement amplitude, m (0 = use acceleration_g)", 0.0, 0.01),
            ("acceleration_g", 0.3, "peak platform acceleration, g (used when amplitude_m = 0)", 0.0, 10.0),
            ("frequency_hz", 35.0, "vibration frequency, Hz (the vibration unit's band)", unit.frequency_min,
             unit.frequency_max),
            ("phase_rad", 0.0, "phase of the platform vibration, rad", -2 * math.pi, 2 * math.pi),
            ("duration_s", 0.0, "vibration duration incl. ramps, s (0 = until stop)", 0.0, 86400.0),
            ("ramp_s", 0.2, "ramp-in / ramp-out time, s", 0.01, 10.0),
            ("lookahead_s", 2.0, "vibration carried by each streamed window before its ramp-out tail, s", 0.05, 60.0),
            ("window_period_s", 0.5, "period between streamed windows, s (< lookahead_s)", 0.01, 30.0),
            ("sample_period_s", 0.001, "sample spacing in a window, s", 1e-4, 0.05),
            ("lead_s", 0.3, "streamed windows start this far ahead of now, s of wall time (more sim seconds when "
             "the sim clock runs faster than real time)", 0.0, 2.0),
            ("start_lead_s", 1.0, "the vibration starts (t0) this far after the start call, s of wall time (>= "
             "lead_s; more sim seconds when the sim clock runs faster than real time)", 0.0, 5.0),
            ("max_lookahead_s", 5.0, "a finite vibration ending within this time is sent whole in one window, s "
             "(the emulator accepts windows reaching up to 30 s ahead)", 0.1, 30.0),
            ("pose_timeout_s", 1.0, "start needs a pose estimate received within this time, s of wall time",
             0.01, 60.0),
        ]
        for name, default, text, low, high in number:
            declare_float(self, name, default, float_param(text, low, high))
        self.add_on_set_parameters_callback(self.on_set_parameters)
        reason = check_settings(self.robot, self.settings())
        if reason:
            raise ValueError(f"invalid initial parameters: {reason}")

        self.diagnostics = Diagnostics(self, "vibration planner")
        self.state = "idle"
        self.last_error = ""
        self.plan = None
        self.stream: VibrationStream | None = None
        self.run = None  # dict: settings, t0 (s), next_send (s)
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
        self.create_subscription(DiagnosticStatus, "vibration/status", self.on_status, STATUS_QOS)
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
            reason = check_settings(self.robot, s)
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

    def on_status(self, msg: DiagnosticStatus) -> None:
        self.diagnostics.seen("vibration/status")
        level = {DiagnosticStatus.OK: "ok", DiagnosticStatus.WARN: "warn"}.get(msg.level, "error")
        report = report_from_values(level, {kv.key: kv.value for kv in msg.values})
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
            end = self.stream.planned_end
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
            pose_stamp, _, position, quaternion = cdr.decode_pose_stamped(data)
            pose = pose_from_position_quaternion(position, quaternion)
        except StewartError as exc:
            return self._refuse(response, f"pose estimate unusable: {exc}")
        # just resumed from a stall, this process may not have taken the latest /clock yet: the
        # fresh pose estimate's stamp (sim time) bounds the present from below
        now = max(now, pose_stamp)
        use_amplitude = s["amplitude_m"] > 0
        duration = s["duration_s"] if s["duration_s"] > 0 else None
        try:
            plan = decompose_vibration(
                self.robot, pose, list(s["direction"]),
                amplitude=s["amplitude_m"] if use_amplitude else None,
                acceleration_g=None if use_amplitude else s["acceleration_g"],
                frequency=s["frequency_hz"], phase=s["phase_rad"], frame=s["frame"], method="exact",
                check_limits=True,
            )
            margin = self.clock_rate.wall_margin  # wall seconds -> sim seconds
            stream = VibrationStream(self.robot, plan, StreamSettings(
                duration=duration, ramp_s=s["ramp_s"], sample_period_s=s["sample_period_s"],
                lookahead_s=s["lookahead_s"], lead_s=margin(s["lead_s"]),
                max_lookahead_s=s["max_lookahead_s"] + margin(s["start_lead_s"]) - s["start_lead_s"]))
            t0 = now + margin(s["start_lead_s"])
            first = stream.next_window(now - t0)
            check_command_limits(self.robot.vibration_unit, first.times, first.position, first.velocity,
                                 first.acceleration)
            if not stream.finished:  # the ramps and the stop ramp too: one stop window at full amplitude
                probe = VibrationStream(self.robot, plan, stream.settings)
                probe.next_window(now - t0)
                stop = probe.stop_window(s["ramp_s"])
                if stop is not None:
                    check_command_limits(self.robot.vibration_unit, stop.times, stop.position, stop.velocity,
                                         stop.acceleration)
        except VibrationLimitError as exc:
            return self._refuse(response, f"infeasible vibration ({type(exc).__name__}): {exc} (with the ramps of "
                                          f"ramp_s {s['ramp_s']} s; a longer ramp_s lowers the peak acceleration)")
        except StewartError as exc:
            return self._refuse(response, f"infeasible vibration ({type(exc).__name__}): {exc}")
        self.plan, self.stream = plan, stream
        self.run = {"settings": s, "t0": t0, "next_send": now + s["window_period_s"]}
        self.state, self.last_error = "running", ""
        self.seen_event = emulator.event_seq if emulator is not None else 0
        self.publish(first)
        acc_g = plan.amplitude * (2 * math.pi * plan.frequency) ** 2 / STANDARD_GRAVITY
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
            # this process was held up (SIGSTOP, a busy machine): the sim clock it sees is stale until
            # the next /clock arrives, so decide on the next tick
            self.get_logger().warning(f"the planner was held up {gap:.3f} s (wall clock)")
            return
        now = self.now_s()
        rel = now - run["t0"]
        end = self.stream.planned_end if self.state == "running" else self.stream.rest_at
        if self.stream.finished and end is not None and rel >= end:
            self.state, self.run = "idle", None
            self._report(OK, "idle")
            return
        if self.stream.finished or now < run["next_send"]:
            return
        run["next_send"] = now + run["settings"]["window_period_s"]
        try:
            window = self.stream.next_window(rel)
        except StreamInterrupted as exc:
            self.abort(str(exc), WARN)
            return
        if window is not None:
            self.publish(window)

    def publish(self, window) -> None:
        started = time.perf_counter()
        self.pub.publish(cdr.encode_joint_trajectory(VIB_NAMES, self.run["t0"], window.times, window.position,
                                                     window.velocity, window.acceleration))
        self.diagnostics.values.update(windows_sent=str(self.stream.windows_sent),
                                       last_window_points=str(len(window.times)),
                                       last_window_encode_ms=f"{(time.perf_counter() - started) * 1e3:.2f}")


def main(args=None) -> int:
    return run_node(VibrationPlannerNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
