"""kinematics node: target poses -> checked minimum-jerk leg trajectories; leg states -> pose estimates.

Topics (relative): sub platform/target_pose (PoseStamped), legs/joint_states
(JointState); pub legs/joint_trajectory (JointTrajectory, leg_* absolute
lengths, m), platform/pose_estimate (PoseStamped, FK of leg_i + vib_i, one per
state with its stamp). Service: kinematics/plan_path (nav_msgs/GetPlan).
Diagnostics on /diagnostics, with the state stream's health (received, lost,
processed, lag). States arrive raw and are solved in vectorised batches of ``batch_size``
(the emulator's bursts) or every ``batch_period_s`` (wall clock; FK warm-started from the previous pose).
"""

from __future__ import annotations

import time

import numpy as np
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
from nav_msgs.srv import GetPlan
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from ..errors import InvalidInputError, StewartError
from ..kinematics import check_pose, forward_kinematics
from ..messages import cdr
from ..messages.stream_health import StreamHealth
from ..motion_profiles import checked_path, interpolate_poses, minimum_jerk, minimum_jerk_duration
from ..robot import load_robot
from ..rotations import pose_to_position_quaternion
from .common import (
    BASE_FRAME,
    LEG_NAMES,
    OK,
    STREAM_DEPTH,
    WARN,
    Diagnostics,
    JointColumns,
    RawBatcher,
    check_frame,
    declare_float,
    duration_msg,
    duration_seconds,
    float_param,
    int_param,
    pose_from_msg,
    pose_stamped,
    reject,
    run_node,
    text_param,
)


class KinematicsNode(Node):
    """Thin adapter over stewart_vibration.kinematics and motion_profiles."""

    def __init__(self):
        super().__init__("kinematics")
        self.declare_parameter("robot_config", "", text_param("robot YAML path ('' = config/robot.yaml)", True))
        self.declare_parameter(
            "trajectory_min_duration_s", 0.5, float_param("shortest point-to-point move, s", 0.05, 120.0)
        )
        self.declare_parameter(
            "trajectory_sample_period_s", 0.02, float_param("spacing of trajectory points, s", 0.001, 1.0)
        )
        self.declare_parameter(
            "speed_scale", 0.5, float_param("fraction of strut_velocity_max used by moves", 0.01, 1.0)
        )
        period = declare_float(self, "batch_period_s", 0.02, float_param(
            "queued states are solved at least this often (wall clock), s (read at start)", 0.001, 0.5,
            read_only=True))
        batch_size = self.declare_parameter("batch_size", 10, int_param(
            "states solved together as soon as this many have queued (read at start)", 1, 1000,
            read_only=True)).value
        path = self.get_parameter("robot_config").value
        self.robot = load_robot(path or None)
        self.diagnostics = Diagnostics(self, "kinematics")
        self.lengths = None  # latest leg_* (strut) lengths, m
        self.pose = None  # latest pose estimate
        self.fk_failures = 0
        self.health = StreamHealth()
        self.columns = JointColumns()
        self.decoder = cdr.JointStateDecoder()
        self.pose_encoder = cdr.PoseStampedEncoder(BASE_FRAME)
        self.batcher = RawBatcher(self, batch_size, period, self.process)
        self.traj_pub = self.create_publisher(JointTrajectory, "legs/joint_trajectory", 10)
        self.pose_pub = self.create_publisher(PoseStamped, "platform/pose_estimate", STREAM_DEPTH)
        # 1 s of states at 500 Hz: under CPU load the executor stalls > 0.1 s and depth 50 lost estimates
        self.create_subscription(JointState, "legs/joint_states", self.batcher.add, STREAM_DEPTH, raw=True)
        self.create_timer(1.0, self.report, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.diagnostics.watch("legs/joint_states", 1.0, "from hardware_emulator")
        self.create_subscription(PoseStamped, "platform/target_pose", self.on_target_pose, 10)
        self.create_service(GetPlan, "kinematics/plan_path", self.on_plan_path)
        self.diagnostics.set(OK, "waiting for legs/joint_states")
        self.get_logger().info(f"kinematics ready (robot {self.robot.source})")

    # -- state estimate ---------------------------------------------------
    def process(self, messages: list, arrivals: np.ndarray) -> None:
        """Solve FK for a batch of states (one batch per layout) and publish one estimate each."""
        self.diagnostics.seen("legs/joint_states")
        try:
            batches = cdr.decode_joint_states(messages, self.decoder)
        except StewartError as exc:
            reject(self, self.diagnostics, "joint states", str(exc))
            self.health.rejected += len(messages)
            return
        first = 0
        for batch in batches:
            n = len(batch.stamps)
            self._solve(batch, arrivals[first:first + n])
            first += n

    def _solve(self, batch, arrivals) -> None:
        self.health.arrived(batch.stamps)
        legs_at, vib_at = self.columns(batch.names)
        if legs_at is None:
            self.health.rejected += len(batch.stamps)
            return
        legs = batch.position[:, legs_at]
        lengths = legs + (batch.position[:, vib_at] if vib_at is not None else 0.0)
        good = np.isfinite(lengths).all(axis=1)
        if not good.all():
            self.health.rejected += int((~good).sum())
            reject(self, self.diagnostics, "joint state", "non-finite leg positions")
            if not good.any():
                return
        lengths, stamps, arrivals, legs = lengths[good], batch.stamps[good], arrivals[good], legs[good]
        guess = self.robot.home_pose if self.pose is None else self.pose
        try:
            result = forward_kinematics(self.robot, lengths, guess=np.broadcast_to(guess, lengths.shape),
                                        check_limits=False)
        except StewartError as exc:
            reject(self, self.diagnostics, "joint state", str(exc))
            return
        ok = result.converged & result.assembly_ok
        if not ok.all():
            self.fk_failures += int((~ok).sum())
            self.diagnostics.set(WARN, "forward kinematics did not converge", fk_failures=self.fk_failures)
            if not ok.any():
                self.pose = None  # cold start next time
                return
        poses = result.pose[ok]
        position, quaternion = pose_to_position_quaternion(poses)
        for stamp, p, q in zip(stamps[ok], position, quaternion, strict=True):
            self.pose_pub.publish(self.pose_encoder.encode(stamp, p, q))
        self.health.done(arrivals[ok], time.monotonic())
        self.lengths, self.pose = legs[ok][-1], poses[-1]
        if self.diagnostics.message == "waiting for legs/joint_states":
            self.diagnostics.set(OK, "tracking")

    def report(self) -> None:
        self.diagnostics.values.update(self.health.values("states"))
        if self.health.behind:
            p99 = self.health.lag_percentiles_ms()[1]
            self.diagnostics.set(WARN, f"falling behind: {self.health.lost} states lost, lag p99 {p99:.1f} ms")
        self.diagnostics.publish()

    # -- target pose -> trajectory ----------------------------------------
    def on_target_pose(self, msg: PoseStamped) -> None:
        try:
            check_frame(msg.header.frame_id, "target pose")
            target = pose_from_msg(msg.pose)
            goal_lengths = check_pose(self.robot, target)
        except StewartError as exc:
            reject(self, self.diagnostics, "target pose", str(exc))
            return
        if self.lengths is None or self.pose is None:
            reject(self, self.diagnostics, "target pose", "no legs/joint_states received yet")
            return
        try:
            trajectory = self.plan_trajectory(self.lengths, self.pose, goal_lengths, target)
        except StewartError as exc:
            reject(self, self.diagnostics, "target pose", f"path not feasible: {exc}")
            return
        self.traj_pub.publish(trajectory)
        final = duration_seconds(trajectory.points[-1].time_from_start)
        self.diagnostics.set(OK, "trajectory sent", last_target=np.round(target, 6).tolist(), last_duration_s=final)
        self.get_logger().info(f"trajectory to {np.round(target, 5).tolist()} over {final:.3f} s")

    def plan_trajectory(self, start_lengths, start_pose, goal_lengths, goal_pose) -> JointTrajectory:
        """Minimum-jerk leg trajectory, every sample checked through FK (stroke, joints, conditioning)."""
        speed = self.robot.limits.strut_velocity_max * self.get_parameter("speed_scale").value
        duration = minimum_jerk_duration(start_lengths, goal_lengths, speed, self.get_parameter(
            "trajectory_min_duration_s").value)
        period = self.get_parameter("trajectory_sample_period_s").value
        count = max(int(np.ceil(duration / period)), 2)
        times = np.linspace(duration / count, duration, count)
        pos, vel, acc = minimum_jerk(start_lengths, goal_lengths, duration, times)
        guesses = interpolate_poses(start_pose, goal_pose, count + 1)[1:]
        fk = forward_kinematics(self.robot, pos, guess=guesses)
        fk.raise_for_failure()
        check_pose(self.robot, fk.pose)
        msg = JointTrajectory()
        msg.header.stamp.sec, msg.header.stamp.nanosec = 0, 0  # start now (joint_trajectory_controller rule)
        msg.joint_names = list(LEG_NAMES)
        for i, t in enumerate(times):
            point = JointTrajectoryPoint()
            point.positions = pos[i].tolist()
            point.velocities = vel[i].tolist()
            point.accelerations = acc[i].tolist()
            point.time_from_start = duration_msg(float(t))
            msg.points.append(point)
        return msg

    # -- plan_path service --------------------------------------------------
    def on_plan_path(self, request: GetPlan.Request, response: GetPlan.Response) -> GetPlan.Response:
        """Checked straight SE(3) path from start to goal (both in base). An unset start (empty frame_id,
        zero position, zero or identity orientation: what a goal-only request carries) means "from the
        current pose estimate". An infeasible request gets an empty path; the reason goes to the log and
        /diagnostics (WARN, value last_plan_failure)."""
        response.plan = Path()
        response.plan.header.frame_id = BASE_FRAME
        response.plan.header.stamp = self.get_clock().now().to_msg()
        try:
            start_msg = request.start
            if unset_pose(start_msg):
                if self.pose is None:
                    raise InvalidInputError("start pose unset and no pose estimate yet")
                start = self.pose
            else:
                check_frame(start_msg.header.frame_id, "plan_path start")
                start = pose_from_msg(start_msg.pose)
            check_frame(request.goal.header.frame_id, "plan_path goal")
            goal = pose_from_msg(request.goal.pose)
            poses = checked_path(self.robot, start, goal)
        except StewartError as exc:
            reason = f"{type(exc).__name__}: {exc}"
            reject(self, self.diagnostics, "plan_path request (empty path returned)", reason)
            self.diagnostics.values["last_plan_failure"] = reason
            return response  # empty path = infeasible
        stamp = response.plan.header.stamp
        response.plan.poses = [pose_stamped(p, stamp) for p in poses]
        self.diagnostics.set(OK, "path planned", last_path_waypoints=len(poses))
        return response


def unset_pose(msg: PoseStamped) -> bool:
    """True for a PoseStamped left at its defaults (no frame, zero position, zero or identity orientation)."""
    p, q = msg.pose.position, msg.pose.orientation
    return msg.header.frame_id == "" and (p.x, p.y, p.z) == (0.0, 0.0, 0.0) and \
        (q.x, q.y, q.z) == (0.0, 0.0, 0.0) and q.w in (0.0, 1.0)


def main(args=None) -> int:
    return run_node(KinematicsNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
