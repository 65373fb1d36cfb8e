"""leg-force estimator node: Newton-Euler leg forces of the measured/commanded platform motion.

Topics (relative): sub legs/joint_states (JointState leg_* + vib_*: position,
velocity, effort), legs/joint_trajectory and vibration/joint_trajectory
(JointTrajectory, the commands the emulator follows), vibration/status (the
emulator's safety ramps); pub legs/force_estimate (JointState leg_*, effort =
modelled axial force N, stamp = the state's), platform/external_wrench_estimate
(WrenchStamped, frame base: the wrench of the environment ON the platform, force
N and moment N m about the platform origin, = -J^T (F_measured - F_model); zero
when the model explains the measurement). Running RMS of F_measured - F_model
and the input stream's health (received, lost, processed, lag) on /diagnostics,
with the count of malformed messages per input (ignored). Started during a
vibration, it takes the first window it sees as its history (value vibration_mirror).

The math and the per-run state are estimation.ForceEstimator (pure). States
arrive raw and are processed in vectorised batches of ``batch_size`` (the
emulator's bursts) or every ``batch_period_s`` (wall clock); every state still
gets its own output messages with its stamp.
"""

from __future__ import annotations

import time

import numpy as np
from geometry_msgs.msg import WrenchStamped
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from stewart_vibration_interfaces.msg import VibrationUnitsStatus

from ..emulation.strut_trajectory import build_trajectory
from ..errors import MalformedMessageError, StewartError
from ..estimation import ForceEstimator
from ..kinematics.robot_config import load_robot
from ..messages.fields import BASE_FRAME
from ..messages.joint_states import JointStateDecoder, JointStateEncoder, decode_joint_states_dropping_malformed
from ..messages.joint_trajectory import decode_joint_trajectory
from ..messages.stamped import MAX_JOINT_POSITION_M, MAX_JOINT_SPEED_M_S, rows_within
from ..messages.stamped_doubles import WrenchStampedEncoder
from ..messages.status_values import vibration_report_from_cdr
from ..messages.stream_health import StreamHealth
from ..parameters.tables import LEG_FORCE_ESTIMATOR
from ..robot import LEG_NAMES, VIB_NAMES
from .diagnostics import OK, WARN, Diagnostics, MalformedInputs, reject
from .message_conversions import JointColumns, RawBatcher, emulator_now
from .node_parameters import declare_table
from .run_loop import STATUS_QOS, STREAM_DEPTH, run_node


class LegForceEstimatorNode(Node):
    """Thin adapter over stewart_vibration.estimation.ForceEstimator."""

    def __init__(self):
        super().__init__("leg_force_estimator")
        params = declare_table(self, LEG_FORCE_ESTIMATOR)
        window, period, batch_size = params["rms_window_s"], params["batch_period_s"], params["batch_size"]
        self.robot = load_robot(self.get_parameter("robot_config").value or None)
        self.estimator = ForceEstimator(self.robot, rms_window_s=window,
                                        unit_sensor_latency_s=params["unit_sensor_latency_s"],
                                        pistons_follow_struts=params["pistons_follow_struts"])
        self.diagnostics = Diagnostics(self, "leg force estimator")
        self.malformed = MalformedInputs(self, self.diagnostics)
        self.health = StreamHealth()
        self.columns = JointColumns()
        self.decoder = JointStateDecoder()
        self.batcher = RawBatcher(self, batch_size, period, self.process)
        self.last_reason = None
        self.force_encoder = JointStateEncoder(LEG_NAMES, BASE_FRAME, fields=("effort",))
        self.wrench_encoder = WrenchStampedEncoder(BASE_FRAME)
        self.force_pub = self.create_publisher(JointState, "legs/force_estimate", STREAM_DEPTH)
        self.wrench_pub = self.create_publisher(WrenchStamped, "platform/external_wrench_estimate", STREAM_DEPTH)
        self.diagnostics.report_readers("legs/force_estimate", self.force_pub)
        self.diagnostics.report_readers("platform/external_wrench_estimate", self.wrench_pub)
        self.create_subscription(JointState, "legs/joint_states", self.batcher.add, STREAM_DEPTH, raw=True)
        self.create_subscription(JointTrajectory, "vibration/joint_trajectory", self.on_vibration, 10, raw=True)
        self.create_subscription(JointTrajectory, "legs/joint_trajectory", self.on_leg_trajectory, 10, raw=True)
        self.create_subscription(VibrationUnitsStatus, "vibration/status", self.on_status, STATUS_QOS, raw=True)
        self.create_timer(1.0, self.report, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.diagnostics.watch("legs/joint_states", 1.0, "from hardware_emulator")
        self.diagnostics.set(OK, "waiting for legs/joint_states")
        self.waiting_for_states = True  # until the first processed state: then "estimating" unless a warning came
        self.get_logger().info(f"leg force estimator ready (robot {self.robot.source})")

    def _malformed(self, error: MalformedMessageError, count: int = 1) -> None:
        self.malformed.refuse("legs/joint_states", error, count)
        self.health.rejected += count

    def _reject(self, what: str, reason: str) -> None:
        """reject() once per distinct reason (inputs arrive at the state rate); every one is counted."""
        self.health.rejected += 1
        if reason != self.last_reason:
            self.last_reason = reason
            reject(self, self.diagnostics, what, reason)

    # -- inputs ---------------------------------------------------------------------------
    def _trajectory(self, data: bytes, names, what: str):
        try:
            t = decode_joint_trajectory(data)
            return build_trajectory(t.names, names, t.stamp, t.times, t.positions, t.velocities, t.accelerations)
        except StewartError as exc:
            self.malformed.refuse(what, exc)
            return None

    def on_vibration(self, data: bytes) -> None:
        traj = self._trajectory(data, VIB_NAMES, "vibration/joint_trajectory")
        if traj is None:
            return
        try:
            adopted = self.estimator.command_vibration(traj)
        except StewartError as exc:  # the emulator refuses it too (its vibration/status says so)
            self._reject("vibration/joint_trajectory", f"refused as the emulator would: {exc}")
            return
        if adopted:
            text = (f"vibration mirror: this estimator started during a vibration; took the window of t0 = "
                    f"{traj.start:.3f} s as its history (the emulator accepted it), later windows splice onto it")
            self.get_logger().warning(text)
            self.diagnostics.set(WARN, text, vibration_mirror=f"adopted a window mid-vibration (t0 {traj.start:.6f} s)")

    def on_leg_trajectory(self, data: bytes) -> None:
        traj = self._trajectory(data, LEG_NAMES, "legs/joint_trajectory")
        if traj is None:
            return
        try:  # from when the emulator takes it: /clock now, not the newest state this node has solved (stale under
            # load: a stop mirrored from there broke the limits and was refused, CI)
            self.estimator.command_struts(traj, now=emulator_now(self, self.estimator.state_time))
        except StewartError as exc:
            self._reject("legs/joint_trajectory", str(exc))

    def on_status(self, data: bytes) -> None:
        """The emulator's safety ramps from its vibration/status (raw); a malformed one is counted and ignored."""
        report = self.malformed.read("vibration/status", vibration_report_from_cdr, data)
        if report is None:
            return
        self.estimator.apply_ramp(report.ramp_start, report.ramp_reason, report.ramp_cause)

    # -- batches --------------------------------------------------------------------------
    def process(self, messages: list, arrivals: np.ndarray) -> None:
        """Modelled forces for a batch of states; one force and one wrench message per state."""
        self.diagnostics.seen("legs/joint_states")
        batches, kept = decode_joint_states_dropping_malformed(
            messages, self.decoder, lambda reason: self._malformed(MalformedMessageError(reason)))
        arrivals = arrivals[kept]
        first = 0
        for batch in batches:
            n = len(batch.stamps)
            self._process_batch(batch, arrivals[first:first + n])
            first += n

    def _process_batch(self, batch, arrivals) -> None:
        legs_at, vib_at = self.columns(batch.names)
        self.health.arrived(batch.stamps)
        if legs_at is None or vib_at is None:
            self._malformed(MalformedMessageError(f"joint state needs {list(LEG_NAMES + VIB_NAMES)} once each, got "
                                                  f"names {list(batch.names)[:14]}", field="name", kind="names"),
                            len(batch.stamps))
            return
        cols = np.concatenate([legs_at, vib_at])
        pos, vel = batch.position[:, cols], batch.velocity[:, cols]
        effort = batch.effort[:, legs_at]
        good = rows_within(pos, MAX_JOINT_POSITION_M) & rows_within(vel, MAX_JOINT_SPEED_M_S)
        if not good.all():
            self._malformed(MalformedMessageError(
                f"{int((~good).sum())} of {len(good)} states without finite positions and velocities (within "
                f"{MAX_JOINT_POSITION_M:g} m and {MAX_JOINT_SPEED_M_S:g} m/s)", field="position", kind="not_finite"),
                int((~good).sum()))
            if not good.any():
                return
        try:
            est = self.estimator.estimate(batch.stamps[good], pos[good, :6], pos[good, 6:], vel[good, :6],
                                          vel[good, 6:], effort[good])
        except StewartError as exc:
            self._reject("joint state", str(exc))
            return
        if not est.ok.all():
            self._reject("joint state", f"forward kinematics failed for {int((~est.ok).sum())} of {len(est.ok)} "
                                        "states")
        for stamp, forces, wrench in zip(est.stamps, est.forces, est.wrench, strict=True):
            self.force_pub.publish(self.force_encoder.encode(stamp, effort=forces))
            if np.isfinite(wrench).all():
                self.wrench_pub.publish(self.wrench_encoder.encode(stamp, wrench))
        self.health.done(arrivals[good][est.ok], time.monotonic())

    def report(self) -> None:
        summary = self.estimator.errors.summary()
        values = self.health.values("states")
        if summary["samples"]:
            values.update(
                rms_error_n=f"{summary['rms_error_all_n']:.6g}",
                rms_error_per_leg_n=str(np.round(summary["rms_error_n"], 6).tolist()),
                force_amplitude_n=str(np.round(summary["force_amplitude_n"], 6).tolist()),
                relative_rms_error=f"{summary['relative_error']:.6g}",
                rms_window_samples=str(summary["samples"]),
            )
        self.diagnostics.values.update(values)
        if self.health.behind:
            p99 = self.health.lag_percentiles_ms()[1]
            self.diagnostics.set(WARN, f"falling behind: {self.health.lost} states lost, lag p99 {p99:.1f} ms")
        elif self.health.processed and self.waiting_for_states:
            self.waiting_for_states = False
            if self.diagnostics.level == OK:  # a rejection (WARN) stays visible with its reason
                self.diagnostics.set(OK, "estimating")
        self.diagnostics.publish()


def main(args=None) -> int:
    """Run the leg-force estimator node until SIGINT / SIGTERM; returns the exit code (2: it cannot start)."""
    return run_node(LegForceEstimatorNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
