"""leg-force estimator node: Newton-Euler leg forces of the measured/commanded platform motion.

Topics (relative): sub legs/joint_states (JointState leg_* + vib_*: position,
velocity, effort), legs/joint_trajectory and vibration/joint_trajectory
(JointTrajectory, the commands the emulator follows); pub legs/force_estimate
(JointState leg_*, effort = modelled axial force N, stamp = the state's),
platform/external_wrench_estimate (WrenchStamped, frame base: the wrench of
the environment ON the platform, force N and moment N m about the platform
origin, = -J^T (F_measured - F_model); zero when the model explains the
measurement). Running RMS of F_measured - F_model on /diagnostics.

Per state: pose = FK of leg_i + vib_i (warm-started); twist = J^-1 (L_dot)
from the measured leg_i + vib_i velocities; acceleration = J^-1 (L_ddot - c)
with L_ddot the commanded leg and vibration accelerations at the state's
stamp (stewart_vibration.estimation). States are queued by the subscription
and processed in vectorised batches every ``batch_period_s``; every state
still gets its own output message with its own stamp.
"""

from __future__ import annotations

import numpy as np
from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from ..dynamics import leg_forces
from ..emulation.trajectory import TrajectoryFollower, build_trajectory
from ..errors import InvalidInputError, StewartError
from ..estimation import (
    RunningForceError,
    VibrationCommandBuffer,
    external_wrench,
    platform_accel,
    platform_twist,
)
from ..kinematics import forward_kinematics
from ..robot import load_robot
from .common import (
    BASE_FRAME,
    LEG_NAMES,
    OK,
    STREAM_DEPTH,
    VIB_NAMES,
    Diagnostics,
    duration_seconds,
    float_param,
    named_values,
    reject,
    run_node,
    stamp_seconds,
    text_param,
)


def _trajectory_arrays(msg: JointTrajectory, names):
    """Validated (start s, JointTrajectory) of a received message; InvalidInputError with the reason."""
    points = msg.points
    return build_trajectory(
        msg.joint_names, names, stamp_seconds(msg.header.stamp),
        [duration_seconds(p.time_from_start) for p in points],
        [p.positions for p in points], [p.velocities for p in points], [p.accelerations for p in points],
    )


class LegForceEstimatorNode(Node):
    """Thin adapter over stewart_vibration.estimation and dynamics.leg_forces."""

    def __init__(self):
        super().__init__("leg_force_estimator")
        self.declare_parameter("robot_config", "", text_param("robot YAML path ('' = config/robot.yaml)", True))
        self.declare_parameter("rms_window_s", 1.0, float_param("window of the running RMS force error, s", 0.01, 60.0))
        self.declare_parameter(
            "batch_period_s", 0.02, float_param("queued states are processed every this period (node clock), s",
                                                0.001, 0.5))
        self.robot = load_robot(self.get_parameter("robot_config").value or None)
        self.diagnostics = Diagnostics(self, "leg force estimator")
        self.vibration = VibrationCommandBuffer()
        self.legs = None  # TrajectoryFollower once a state gives the held positions
        self.pose = None  # last FK pose (warm start)
        self.pending = []  # (stamp, L, L_dot, F_measured or None, header stamp msg, leg positions)
        self.errors = RunningForceError(self.get_parameter("rms_window_s").value)
        self.processed = 0
        self.last_reason = None
        self.force_pub = self.create_publisher(JointState, "legs/force_estimate", STREAM_DEPTH)
        self.wrench_pub = self.create_publisher(WrenchStamped, "platform/external_wrench_estimate", STREAM_DEPTH)
        self.create_subscription(JointState, "legs/joint_states", self.on_joint_states, STREAM_DEPTH)
        self.create_subscription(JointTrajectory, "vibration/joint_trajectory", self.on_vibration, 10)
        self.create_subscription(JointTrajectory, "legs/joint_trajectory", self.on_leg_trajectory, 10)
        self.create_timer(self.get_parameter("batch_period_s").value, self.process)
        self.create_timer(1.0, self.report)
        self.diagnostics.set(OK, "waiting for legs/joint_states")
        self.get_logger().info(f"leg force estimator ready (robot {self.robot.source})")

    def _reject(self, what: str, reason: str) -> None:
        """reject() once per distinct reason (inputs arrive at the state rate)."""
        self.diagnostics.values["rejected_count"] = str(int(self.diagnostics.values.get("rejected_count", 0)) + 1)
        if reason != self.last_reason:
            self.last_reason = reason
            reject(self, self.diagnostics, what, reason)

    # -- inputs -------------------------------------------------------------
    def on_joint_states(self, msg: JointState) -> None:
        table = {}
        for field in ("position", "velocity"):
            legs = named_values(msg.name, getattr(msg, field), LEG_NAMES)
            vib = named_values(msg.name, getattr(msg, field), VIB_NAMES)
            if legs is None or vib is None:
                self._reject("joint state", f"needs {field} for {LEG_NAMES + VIB_NAMES}, got names {list(msg.name)}")
                return
            table[field] = (legs, vib)
        effort = named_values(msg.name, msg.effort, LEG_NAMES) if len(msg.effort) else None
        values = [*table["position"], *table["velocity"]] + ([effort] if effort is not None else [])
        if not all(np.isfinite(v).all() for v in values):
            self._reject("joint state", "non-finite position, velocity or effort")
            return
        stamp = stamp_seconds(msg.header.stamp)
        legs, vib = table["position"]
        self.pending.append((stamp, legs + vib, sum(table["velocity"]), effort, msg.header.stamp, legs))

    def on_vibration(self, msg: JointTrajectory) -> None:
        try:
            traj = _trajectory_arrays(msg, VIB_NAMES)
            if traj.velocities is None:
                raise InvalidInputError("vibration windows need velocities")
            start = traj.start if traj.start > 0 else self.get_clock().now().nanoseconds * 1e-9
            self.vibration.add(start + traj.times, traj.positions, traj.velocities)
        except StewartError as exc:
            self._reject("vibration/joint_trajectory", str(exc))

    def on_leg_trajectory(self, msg: JointTrajectory) -> None:
        try:
            traj = _trajectory_arrays(msg, LEG_NAMES)
        except StewartError as exc:
            self._reject("legs/joint_trajectory", str(exc))
            return
        now = self.get_clock().now().nanoseconds * 1e-9
        if self.legs is None:
            if self.pending:
                self.legs = TrajectoryFollower(self.pending[-1][5])
            else:
                self._reject("legs/joint_trajectory", "no legs/joint_states yet (start state unknown)")
                return
        self.legs.replace(traj, now)

    # -- batch processing -----------------------------------------------------
    def process(self) -> None:
        if not self.pending:
            return
        batch, self.pending = self.pending, []
        stamps = np.array([b[0] for b in batch])
        lengths = np.array([b[1] for b in batch])
        rates = np.array([b[2] for b in batch])
        if self.legs is None:
            self.legs = TrajectoryFollower(batch[-1][5])
        elif self.legs.finished(stamps[-1]):
            self.legs.hold(batch[-1][5])  # at rest at the measured lengths
        try:
            guess = self.robot.home_pose if self.pose is None else self.pose
            fk = forward_kinematics(self.robot, lengths, guess=np.broadcast_to(guess, lengths.shape),
                                    check_limits=False)
            ok = fk.converged & fk.assembly_ok
            if not ok.all():
                self._reject("joint state", f"forward kinematics failed for {int((~ok).sum())} of {len(ok)} states")
                if not ok.any():
                    self.pose = None
                    return
            pose = fk.pose[ok]
            twist = platform_twist(self.robot, pose, rates[ok])
            accel_legs = self.legs.sample(stamps[ok])[2] + self.vibration.sample(stamps[ok])[2]
            accel = platform_accel(self.robot, pose, twist, accel_legs)
            model = leg_forces(self.robot, pose, twist, accel)
        except StewartError as exc:
            self._reject("joint state", str(exc))
            return
        self.pose = pose[-1]
        kept = [b for b, good in zip(batch, ok) if good]
        for i, (stamp, _, _, effort, stamp_msg, _) in enumerate(kept):
            out = JointState()
            out.header.stamp = stamp_msg
            out.header.frame_id = BASE_FRAME
            out.name = list(LEG_NAMES)
            out.effort = model[i].tolist()
            self.force_pub.publish(out)
            if effort is None:
                continue
            wrench = external_wrench(self.robot, pose[i], effort, model[i])
            msg = WrenchStamped()
            msg.header.stamp = stamp_msg
            msg.header.frame_id = BASE_FRAME
            f, m = msg.wrench.force, msg.wrench.torque
            f.x, f.y, f.z, m.x, m.y, m.z = (float(v) for v in wrench)
            self.wrench_pub.publish(msg)
            self.errors.add(stamp, effort, model[i])
        self.processed += len(kept)

    def report(self) -> None:
        summary = self.errors.summary()
        if summary["samples"]:
            self.diagnostics.values.update(
                rms_error_n=f"{summary['rms_error_all_n']:.6g}",
                rms_error_per_leg_n=str(np.round(summary["rms_error_n"], 6).tolist()),
                force_amplitude_n=str(np.round(summary["force_amplitude_n"], 6).tolist()),
                relative_rms_error=f"{summary['relative_error']:.6g}",
                rms_window_samples=str(summary["samples"]),
            )
        self.diagnostics.values["states_processed"] = str(self.processed)
        if self.processed and self.diagnostics.message == "waiting for legs/joint_states":
            self.diagnostics.set(OK, "estimating")  # a rejection (WARN) stays visible with its reason
        self.diagnostics.publish()


def main(args=None) -> None:
    run_node(LegForceEstimatorNode, args)


if __name__ == "__main__":
    main()
