"""vibration planner node: a vibration session (action) -> self-contained vib_* command windows.

Action vibration_planner/vibrate (stewart_vibration_interfaces/action/Vibrate): the goal carries the
vibration (direction and frame, amplitude or acceleration, frequency, phase, duration, ramp); the node's
parameters are only the streaming's timing (lookahead_s, window_period_s, sample_period_s, lead_s,
start_lead_s, max_lookahead_s, pose_timeout_s). Feedback at 10 Hz: the units' state, the plan, the time
since t0 and what the sensors show delivered (analysis.delivered_from_poses). Result: the outcome (a code of
the one table), the plan, the active time and the cycles delivered. Cancel = a ramp-out over ramp_s. One
vibration at a time: a goal while one runs ends at once with BUSY (nodes.vibrate_server). Action
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
from typing import cast

from geometry_msgs.msg import PoseStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, JointState
from trajectory_msgs.msg import JointTrajectory

from stewart_vibration_interfaces.msg import VibrationUnitsStatus

from ..kinematics.robot_config import load_robot
from ..messages.joint_states import JointStateDecoder
from ..messages.stamped_doubles import decode_imu
from ..messages.status_values import vibration_report_from_cdr
from ..parameters.tables import VIBRATION_PLANNER
from ..runtime.sim_clock import ClockRate
from ..vibration.delivery_run import DeliveryRun
from ..vibration.planner_parameters import parameter_change
from ..vibration.settings import STREAM_KEYS, default_settings, settings_reason
from ..vibration.start_gate import check_can_start
from ..vibration.unit_identification import load_identification_option
from .diagnostics import OK, Diagnostics, MalformedInputs, reject
from .identification_server import IdentificationServer
from .node_parameters import declare_table
from .outcomes import outcome
from .run_loop import STATUS_QOS, run_node
from .vibrate_server import VibrateServer

POLL_PERIOD_S = 0.01  # wall-clock polling of the sim clock for the streaming
STALL_S = 0.1  # a tick this late means the process was held up: skip it (the sim clock is stale)
STATUS_STALE_S = 2.5  # wall s: the emulator repeats its status every second, so an older one is stale
IMU_QOS = QoSProfile(depth=500, reliability=ReliabilityPolicy.RELIABLE)  # 1 s of samples: bursts of 10 every 20 ms


class VibrationPlannerNode(Node):
    """The planner's inputs, parameters, start gate, streaming clock and diagnostics, which its vibrate action
    (nodes.vibrate_server, over vibration.delivery_run) and identify action (nodes.identification_server) share."""

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
        # raw PoseStamped bytes and their receive time (monotonic wall s: the sim clock may be stale when this
        # process resumes from a stall); the latest VibrationReport and when it arrived (monotonic wall s)
        self.pose_data: tuple[bytes, float] | None = None
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
        self.vibrate = VibrateServer(self)
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

    # -- inputs ------------------------------------------------------------------------
    def now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def on_pose(self, data: bytes) -> None:
        """Keep the latest estimate (500 Hz: decoded only when a vibration starts or feedback is due)."""
        self.pose_data = (data, time.monotonic())
        if self.vibrate.run is not None:
            self.vibrate.recent_poses.append(data)
        self._pose_seen += 1
        if self._pose_seen % 50 == 1:  # the freshness watch needs no more than a few per second
            self.diagnostics.seen("platform/pose_estimate")

    def on_imu(self, data: bytes) -> None:
        """A platform IMU sample for the identification or the running vibration's closed loop (else ignored)."""
        run, ident = self.vibrate.run, self.identify.runner
        if (ident is None and (run is None or not run.listens_to_imu)) or \
                (sample := self.malformed.read("platform/imu", decode_imu, data)) is None:
            return
        stamp, _, rate, accel = sample
        if ident is not None:
            ident.add_imu(stamp, accel, rate)
        elif reason := cast(DeliveryRun, run).add_imu(stamp, accel, rate):
            self.vibrate.act(cast(DeliveryRun, run).delivery_limit(self.now_s(), reason))

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
        elif self.vibrate.run is not None and (end := self.vibrate.run.on_status(report)) is not None:
            self.vibrate.end(end)

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

    # -- streaming ---------------------------------------------------------------------------
    def tick(self) -> None:
        wall = time.monotonic()
        gap, self._last_tick = wall - self._last_tick, wall
        if gap <= STALL_S and wall - self._last_rate_sample >= 0.05:
            self._last_rate_sample = wall
            self.clock_rate.add(wall, self.now_s())
        if (runner := self.identify.runner) is not None:
            self.identify.tick(runner)
        elif (run := self.vibrate.run) is not None and gap > STALL_S:
            # held up (SIGSTOP, a busy machine): the sim clock is stale
            self.get_logger().warning(f"the planner was held up {gap:.3f} s (wall clock)")
            self.vibrate.act(run.after_stall(gap * self.clock_rate.rate()))
        elif run is not None:
            self.vibrate.act(run.tick(self.now_s(), wall))

    # -- state ---------------------------------------------------------------------------
    def report(self, level, message: str) -> None:
        self.diagnostics.set(level, message, state=self.state, last_error=self.last_error or "none",
                             windows_sent=self.vibrate.stream.windows_sent if self.vibrate.stream else 0,
                             t0_s=f"{self.vibrate.run.t0:.6f}" if self.vibrate.run else "")

    def shutdown(self) -> None:
        """A vibration still running ramps out (its goal ends SHUTDOWN): the units never keep a stale stream."""
        self.vibrate.shutdown()


def main(args=None) -> int:
    """Run the vibration planner node until SIGINT / SIGTERM; returns the exit code (2: it cannot start)."""
    return run_node(VibrationPlannerNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
