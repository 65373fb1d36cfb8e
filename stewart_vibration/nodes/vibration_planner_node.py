"""vibration planner node: a platform vibration -> streamed vib_* command windows.

Topics (relative): sub platform/pose_estimate (PoseStamped); pub
vibration/joint_trajectory (JointTrajectory vib_1..vib_6: positions m and
velocities m/s; header.stamp = the vibration's common start time t0,
time_from_start relative to t0). Services vibration_planner/start and
vibration_planner/stop (std_srvs/Trigger). Diagnostics on /diagnostics
(state idle/running/stopping, last error, the running plan).

Protocol (node clock, i.e. sim time under use_sim_time):
- start (only when idle; while running or stopping it is refused with
  "already running", call stop first): needs a pose estimate received within
  pose_timeout_s; decomposes the vibration at that pose (exact IK method,
  decompose_vibration with limit checks), checks the per-leg peaks including
  the ramps, sets t0 = now + start_lead_s and streams. start_lead_s (1 s)
  is the margin for the first window to reach the emulator before t0 even
  when this node's clock lags the emulator's (a loaded machine): the emulator
  refuses a first window that arrives after its vibration has begun.
- windows: every window_period_s one message with the samples of the grid
  t0 + k sample_period_s inside [s, s + window_s], s = max(now + lead_s, t0)
  (clipped to t0 + duration); consecutive windows overlap and agree
  sample for sample. The vibration ramps in from rest over ramp_s (first
  sample 0) and, with duration_s > 0, ramps out to 0 at t0 + duration_s.
- stop: one last window from now + lead_s to now + lead_s + ramp_s in which
  the vibration is multiplied by a quintic ramp to zero (no step: the ramp
  starts at 1 on the already-sent samples), then no more windows; state
  "stopping" until the ramp is over, then "idle". stop when idle succeeds
  with "already idle".
Parameters changed while running apply to the next start. If the node dies
while vibrating, the emulator's watchdog ramps the vibration out (the ROS
context is already gone at shutdown, so no last window can be sent).
"""

from __future__ import annotations

import math

import numpy as np
from builtin_interfaces.msg import Time as TimeMsg
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.msg import ParameterDescriptor, ParameterType, SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from ..errors import StewartError, VibrationLimitError
from ..robot import STANDARD_GRAVITY, load_robot
from ..vibration import decompose_vibration, envelope, sample_leg_vibration
from ..vibration.decompose import FRAMES
from ..vibration.feasibility import check_leg_peaks
from .common import (
    ERROR,
    OK,
    VIB_NAMES,
    WARN,
    Diagnostics,
    duration_msg,
    float_param,
    pose_from_msg,
    reject,
    run_node,
    text_param,
)

POLL_PERIOD_S = 0.01  # wall-clock polling of the sim clock for the streaming
SMOOTHSTEP_RATE_MAX = 1.875  # max ds/dx of the quintic smoothstep
SMOOTHSTEP_CURVATURE_MAX = 10.0 / math.sqrt(3.0)  # max |d2s/dx2|


def ramp_acceleration_bound(plan, ramp_s: float) -> np.ndarray:
    """Per-leg peak acceleration bound (m/s^2) of the ramped leg vibration (ramp-in, ramp-out or stop).

    d2/dt2 (e x) = e x'' + 2 e' x' + e'' x with |x'| <= omega |x|max, so the
    steady peak grows by at most |x|max (2 omega max|e'| + max|e''|).
    """
    peak = np.maximum(np.abs(plan.peak_change_low), np.abs(plan.peak_change_high))
    omega = 2.0 * np.pi * plan.frequency
    return plan.peak_leg_acceleration + peak * (
        2.0 * omega * SMOOTHSTEP_RATE_MAX / ramp_s + SMOOTHSTEP_CURVATURE_MAX / ramp_s**2
    )


class VibrationPlannerNode(Node):
    """Thin adapter over stewart_vibration.vibration (decompose, sample_leg_vibration)."""

    def __init__(self):
        super().__init__("vibration_planner")
        self.declare_parameter("robot_config", "", text_param("robot YAML path ('' = config/robot.yaml)", True))
        self.robot = load_robot(self.get_parameter("robot_config").value or None)
        unit = self.robot.vibration_unit
        self.declare_parameter("direction", [0.0, 0.0, 1.0], ParameterDescriptor(
            type=ParameterType.PARAMETER_DOUBLE_ARRAY,
            description="vibration direction (3 values, any non-zero length) in `frame`"))
        self.declare_parameter("frame", "platform", text_param("frame of `direction`: platform | base"))
        self.declare_parameter("amplitude_m", 0.0, float_param(
            "platform displacement amplitude, m (0 = use acceleration_g)", 0.0, 0.01))
        self.declare_parameter("acceleration_g", 0.3, float_param(
            "peak platform acceleration, g (used when amplitude_m = 0)", 0.0, 10.0))
        self.declare_parameter("frequency_hz", 35.0, float_param(
            "vibration frequency, Hz (the vibration unit's band)", unit.frequency_min, unit.frequency_max))
        self.declare_parameter("phase_rad", 0.0, float_param("phase of the platform vibration, rad",
                                                             -2 * math.pi, 2 * math.pi))
        self.declare_parameter("duration_s", 0.0, float_param("vibration duration incl. ramps, s (0 = until stop)",
                                                              0.0, 86400.0))
        self.declare_parameter("ramp_s", 0.2, float_param("ramp-in / ramp-out time, s", 0.01, 10.0))
        self.declare_parameter("window_s", 0.6, float_param("span of each streamed window, s", 0.05, 10.0))
        self.declare_parameter("window_period_s", 0.2, float_param(
            "period between windows, s (< the emulator's 0.5 s watchdog)", 0.01, 0.4))
        self.declare_parameter("sample_period_s", 0.001, float_param("sample spacing in a window, s", 1e-4, 0.05))
        self.declare_parameter("lead_s", 0.3, float_param("windows start this far ahead of now, s", 0.0, 2.0))
        self.declare_parameter("start_lead_s", 1.0, float_param(
            "the vibration starts (t0) this far after the start call, s (>= lead_s)", 0.0, 5.0))
        self.declare_parameter("pose_timeout_s", 1.0, float_param(
            "start needs a pose estimate received within this time, s", 0.01, 60.0))
        self.add_on_set_parameters_callback(self.on_set_parameters)
        reason = self.check_settings(self.settings())
        if reason:
            raise ValueError(f"invalid initial parameters: {reason}")

        self.diagnostics = Diagnostics(self, "vibration planner")
        self.state = "idle"
        self.last_error = ""
        self.plan = None
        self.run = None  # dict of the running vibration's settings
        self.timer = None
        self.windows_sent = 0
        self.pose_msg = None
        self.pose_received_ns = None
        self.pub = self.create_publisher(JointTrajectory, "vibration/joint_trajectory", 10)
        self.create_subscription(PoseStamped, "platform/pose_estimate", self.on_pose, 10)
        self.create_service(Trigger, "vibration_planner/start", self.on_start)
        self.create_service(Trigger, "vibration_planner/stop", self.on_stop)
        self._report(OK, "idle")
        self.get_logger().info(f"vibration planner ready (robot {self.robot.source})")

    # -- parameters -----------------------------------------------------------
    NAMES = ("direction", "frame", "amplitude_m", "acceleration_g", "frequency_hz", "phase_rad", "duration_s",
             "ramp_s", "window_s", "window_period_s", "sample_period_s", "lead_s", "start_lead_s", "pose_timeout_s")

    def settings(self) -> dict:
        return {name: self.get_parameter(name).value for name in self.NAMES}

    def check_settings(self, s: dict) -> str | None:
        """The reason the settings are invalid, or None."""
        unit = self.robot.vibration_unit
        direction = np.asarray(list(s["direction"]), dtype=float)
        if direction.shape != (3,) or not np.isfinite(direction).all() or np.linalg.norm(direction) < 1e-9:
            return f"direction must be 3 finite values, not all zero; got {list(s['direction'])}"
        if s["frame"] not in FRAMES:
            return f"frame must be one of {list(FRAMES)}, got {s['frame']!r}"
        numbers = {k: v for k, v in s.items() if k not in ("direction", "frame")}
        for name, value in numbers.items():
            if not math.isfinite(value):
                return f"{name} must be finite, got {value}"
        if not unit.frequency_min <= s["frequency_hz"] <= unit.frequency_max:
            return (f"frequency_hz {s['frequency_hz']} is outside the vibration unit's band "
                    f"[{unit.frequency_min}, {unit.frequency_max}] Hz")
        if s["amplitude_m"] < 0:
            return f"amplitude_m must be >= 0, got {s['amplitude_m']}"
        if s["amplitude_m"] == 0 and s["acceleration_g"] <= 0:
            return "acceleration_g must be > 0 when amplitude_m = 0"
        if s["ramp_s"] <= 0:
            return f"ramp_s must be > 0, got {s['ramp_s']}"
        if s["duration_s"] != 0 and s["duration_s"] < 2 * s["ramp_s"]:
            return f"duration_s {s['duration_s']} must be 0 (until stop) or >= 2 ramp_s = {2 * s['ramp_s']}"
        if s["window_s"] <= s["window_period_s"]:
            return f"window_s {s['window_s']} must exceed window_period_s {s['window_period_s']} (gapless stream)"
        if s["start_lead_s"] < s["lead_s"]:
            return f"start_lead_s {s['start_lead_s']} must be >= lead_s {s['lead_s']} (the first window starts at t0)"
        if s["sample_period_s"] * 2 > s["window_s"]:
            return f"sample_period_s {s['sample_period_s']} must be <= window_s / 2"
        if s["sample_period_s"] * s["frequency_hz"] > 0.1:
            return (f"sample_period_s {s['sample_period_s']} is too coarse for {s['frequency_hz']} Hz "
                    "(need >= 10 samples per period)")
        return None

    def on_set_parameters(self, params) -> SetParametersResult:
        s = self.settings()
        for p in params:
            if p.name in s:
                s[p.name] = p.value
        try:
            reason = self.check_settings(s)
        except (TypeError, ValueError) as exc:
            reason = f"invalid parameter value: {exc}"
        if reason:
            if hasattr(self, "diagnostics"):
                reject(self, self.diagnostics, "parameters", reason)
            return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    # -- inputs -----------------------------------------------------------------
    def now_ns(self) -> int:
        return self.get_clock().now().nanoseconds

    def on_pose(self, msg: PoseStamped) -> None:
        """Keep the latest estimate (500 Hz: converted only when a vibration starts)."""
        self.pose_msg, self.pose_received_ns = msg, self.now_ns()



    def _report(self, level, message: str) -> None:
        self.diagnostics.set(level, message, state=self.state, last_error=self.last_error or "none",
                             windows_sent=self.windows_sent)

    def _fail(self, response, reason: str):
        self.last_error = reason
        response.success, response.message = False, reason
        reject(self, self.diagnostics, "start", reason)
        self.diagnostics.set(WARN, f"rejected start: {reason}", state=self.state, last_error=reason)
        return response

    # -- services -----------------------------------------------------------------
    def on_start(self, request, response):
        if self.state != "idle":
            return self._fail(response, f"already running (state {self.state}); call stop first")
        if self.pose_msg is None:
            return self._fail(response, "no platform/pose_estimate received yet")
        try:
            pose = pose_from_msg(self.pose_msg.pose)
        except StewartError as exc:
            return self._fail(response, f"pose estimate unusable: {exc}")
        now = self.now_ns()
        if now <= 0:
            return self._fail(response, "clock not running (use_sim_time without /clock?)")
        s = self.settings()
        age = (now - self.pose_received_ns) * 1e-9
        if age > s["pose_timeout_s"]:
            return self._fail(response, f"pose estimate is {age:.3f} s old (pose_timeout_s {s['pose_timeout_s']})")
        use_amplitude = s["amplitude_m"] > 0
        try:
            plan = decompose_vibration(
                self.robot, pose, list(s["direction"]),
                amplitude=s["amplitude_m"] if use_amplitude else None,
                acceleration_g=None if use_amplitude else s["acceleration_g"],
                frequency=s["frequency_hz"], phase=s["phase_rad"], frame=s["frame"], method="exact",
                check_limits=True,
            )
            bound = ramp_acceleration_bound(plan, s["ramp_s"])
            try:
                check_leg_peaks(self.robot, np.zeros(6), bound)  # amplitudes were checked above
            except VibrationLimitError as exc:
                raise VibrationLimitError(
                    f"{exc} with the ramps of ramp_s {s['ramp_s']} s (use a longer ramp_s)",
                    leg=exc.leg, limit_name=exc.limit_name, value=exc.value, limit=exc.limit) from exc
        except StewartError as exc:
            return self._fail(response, f"infeasible vibration ({type(exc).__name__}): {exc}")
        self.plan = plan
        self.run = dict(s, t0_ns=now + int(round(s["start_lead_s"] * 1e9)),
                        end=s["duration_s"] if s["duration_s"] > 0 else None, stop_end=None, final_sent=False)
        self.state, self.last_error, self.windows_sent = "running", "", 0
        self.send_window(now)
        self.next_send_ns = now + int(round(s["window_period_s"] * 1e9))
        # poll on a steady (wall) timer and send by the node clock (sim time): robust at any
        # real-time factor, and independent of how an executor schedules sim-time timers
        self.timer = self.create_timer(POLL_PERIOD_S, self.tick, clock=Clock(clock_type=ClockType.STEADY_TIME))
        acc_g = plan.amplitude * (2 * math.pi * plan.frequency) ** 2 / STANDARD_GRAVITY
        text = (
            f"started: {plan.frequency:g} Hz, platform amplitude {plan.amplitude * 1e6:.3f} um ({acc_g:.3f} g) "
            f"along {np.round(plan.direction, 6).tolist()} (base frame), phase {plan.phase:.4f} rad, "
            f"t0 = {self.run['t0_ns'] * 1e-9:.6f} s, ramp {s['ramp_s']} s, "
            f"duration {'until stop' if self.run['end'] is None else str(self.run['end']) + ' s'}; "
            f"gains k = {np.round(plan.gains, 6).tolist()}; "
            f"leg amplitudes um = {np.round(plan.leg_amplitudes * 1e6, 3).tolist()}; "
            f"leg phases rad = {np.round(plan.leg_phases, 4).tolist()}"
        )
        self.get_logger().info(text)
        self.diagnostics.set(OK, "running", frequency_hz=plan.frequency, amplitude_um=plan.amplitude * 1e6,
                             gains=np.round(plan.gains, 6).tolist(),
                             leg_amplitudes_um=np.round(plan.leg_amplitudes * 1e6, 3).tolist())
        self._report(OK, "running")
        response.success, response.message = True, text
        return response

    def on_stop(self, request, response):
        if self.state == "idle":
            response.success, response.message = True, "already idle"
            return response
        if self.state == "stopping":
            response.success, response.message = True, "already stopping"
            return response
        run = self.run
        now = self.now_ns()
        rel_now = (now - run["t0_ns"]) * 1e-9 + run["lead_s"]
        dt = run["sample_period_s"]
        rel_now = max(math.ceil(rel_now / dt - 1e-6) * dt, 0.0)  # the ramp starts on a sent sample, at 1
        stop_end = rel_now + run["ramp_s"]
        if run["end"] is not None and stop_end >= run["end"]:
            response.success = True
            response.message = f"the vibration already ends at t0 + {run['end']} s; letting it ramp out"
            return response
        run["stop_end"] = stop_end
        self.send_window(now)
        run["final_sent"] = True
        self.state = "stopping"
        self._report(OK, "stopping")
        response.success = True
        response.message = (f"stopping: ramp-out from t0 + {rel_now:.4f} s over {run['ramp_s']} s, "
                            f"at rest at t0 + {stop_end:.4f} s")
        self.get_logger().info(response.message)
        return response

    # -- streaming ----------------------------------------------------------------
    def tick(self) -> None:
        run = self.run
        if run is None:
            return
        now = self.now_ns()
        rel_now = (now - run["t0_ns"]) * 1e-9
        end = run["stop_end"] if run["stop_end"] is not None else run["end"]
        if end is not None and rel_now >= end:
            self.state, self.run = "idle", None
            if self.timer is not None:
                self.destroy_timer(self.timer)
                self.timer = None
            self._report(OK, "idle")
            return
        if not run["final_sent"] and now >= self.next_send_ns:
            self.next_send_ns = now + int(round(run["window_period_s"] * 1e9))
            try:
                self.send_window(now)
            except StewartError as exc:  # should not happen: start checked the peaks with the ramps
                self.last_error = str(exc)
                self._report(ERROR, f"window not sent: {exc}")

    def window_times(self, now_ns: int) -> np.ndarray:
        """Relative sample times (s from t0) of the window to send at ``now_ns``."""
        run = self.run
        dt = run["sample_period_s"]
        start = max((now_ns - run["t0_ns"]) * 1e-9 + run["lead_s"], 0.0)
        stop = start + run["window_s"]
        end = run["stop_end"] if run["stop_end"] is not None else run["end"]
        if run["stop_end"] is not None:
            stop = end
        if end is not None:
            stop = min(stop, end)
        k0, k1 = math.ceil(start / dt - 1e-6), math.floor(stop / dt + 1e-6)
        times = np.arange(k0, k1 + 1) * dt
        if end is not None and stop >= end - 1e-12:
            run["final_sent"] = True
            if times.size == 0 or times[-1] < end - 1e-9:
                times = np.append(times, end)
        return times

    def send_window(self, now_ns: int) -> None:
        run = self.run
        times = self.window_times(now_ns)
        if times.size < 2:
            return
        ramp = run["ramp_s"]
        samples = sample_leg_vibration(self.robot, self.plan, times, duration=run["end"], ramp_time=ramp)
        pos, vel, acc = samples.position, samples.velocity, samples.acceleration
        if run["stop_end"] is not None:
            # g(t) = e(stop_end - t): dg/dt = -rate, d2g/dt2 = second
            g, rate, second = envelope(run["stop_end"] - times, None, ramp)
            g, rate, second = g[:, None], rate[:, None], second[:, None]
            pos, vel, acc = g * pos, g * vel - rate * pos, g * acc - 2.0 * rate * vel + second * pos
        else:
            check_leg_peaks(self.robot, np.abs(pos).max(axis=0), np.abs(acc).max(axis=0))
        msg = JointTrajectory()
        t0 = run["t0_ns"]
        msg.header.stamp = TimeMsg(sec=t0 // 1_000_000_000, nanosec=t0 % 1_000_000_000)
        msg.joint_names = list(VIB_NAMES)
        msg.points = [
            JointTrajectoryPoint(positions=p, velocities=v, time_from_start=duration_msg(float(t)))
            for t, p, v in zip(times, pos.tolist(), vel.tolist())
        ]
        self.pub.publish(msg)
        self.windows_sent += 1
        self.diagnostics.values["windows_sent"] = str(self.windows_sent)


def main(args=None) -> None:
    run_node(VibrationPlannerNode, args)


if __name__ == "__main__":
    main()
