"""kinematics node: target poses -> checked minimum-jerk leg trajectories; leg states -> pose estimates.

Topics (relative): sub platform/target_pose (PoseStamped), legs/joint_states
(JointState); pub legs/joint_trajectory (JointTrajectory, leg_* absolute
lengths, m), platform/pose_estimate (PoseStamped, FK of leg_i + vib_i).
Service: kinematics/plan_path (nav_msgs/GetPlan). Diagnostics on /diagnostics.
"""

from __future__ import annotations

import numpy as np
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
from nav_msgs.srv import GetPlan
from rclpy.node import Node
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from ..errors import StewartError
from ..kinematics import check_pose, forward_kinematics
from ..motion_profiles import checked_path, interpolate_poses, minimum_jerk, minimum_jerk_duration
from ..robot import load_robot
from .common import (
    LEG_NAMES,
    OK,
    STREAM_DEPTH,
    VIB_NAMES,
    WARN,
    Diagnostics,
    duration_msg,
    duration_seconds,
    float_param,
    named_values,
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
        path = self.get_parameter("robot_config").value
        self.robot = load_robot(path or None)
        self.diagnostics = Diagnostics(self, "kinematics")
        self.lengths = None  # latest leg_* (strut) lengths, m
        self.pose = None  # latest pose estimate
        self.fk_failures = 0
        self.traj_pub = self.create_publisher(JointTrajectory, "legs/joint_trajectory", 10)
        self.pose_pub = self.create_publisher(PoseStamped, "platform/pose_estimate", STREAM_DEPTH)
        # 1 s of states at 500 Hz: under CPU load the executor stalls > 0.1 s and depth 50 lost estimates
        self.create_subscription(JointState, "legs/joint_states", self.on_joint_states, STREAM_DEPTH)
        self.create_subscription(PoseStamped, "platform/target_pose", self.on_target_pose, 10)
        self.create_service(GetPlan, "kinematics/plan_path", self.on_plan_path)
        self.diagnostics.set(OK, "waiting for legs/joint_states")
        self.get_logger().info(f"kinematics ready (robot {self.robot.source})")

    # -- state estimate ---------------------------------------------------
    def on_joint_states(self, msg: JointState) -> None:
        legs = named_values(msg.name, msg.position, LEG_NAMES)
        if legs is None:
            return
        vib = named_values(msg.name, msg.position, VIB_NAMES)
        hinge_lengths = legs + (vib if vib is not None else 0.0)
        try:
            result = forward_kinematics(self.robot, hinge_lengths, guess=self.pose, check_limits=False)
        except StewartError as exc:
            reject(self, self.diagnostics, "joint state", str(exc))
            return
        if not (result.converged and result.assembly_ok):
            self.fk_failures += 1
            self.pose = None  # cold start next time
            self.diagnostics.set(WARN, "forward kinematics did not converge", fk_failures=self.fk_failures)
            return
        self.lengths = legs
        self.pose = result.pose
        self.pose_pub.publish(pose_stamped(result.pose, msg.header.stamp))
        if self.diagnostics.message == "waiting for legs/joint_states":
            self.diagnostics.set(OK, "tracking")

    # -- target pose -> trajectory ----------------------------------------
    def on_target_pose(self, msg: PoseStamped) -> None:
        try:
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
        response.plan = Path()
        response.plan.header.frame_id = "base"
        response.plan.header.stamp = self.get_clock().now().to_msg()
        try:
            q = request.start.pose.orientation
            if (q.x, q.y, q.z, q.w) == (0.0, 0.0, 0.0, 0.0):  # unset start: use the current estimate
                if self.pose is None:
                    raise ValueError("start pose unset and no pose estimate yet")
                start = self.pose
            else:
                start = pose_from_msg(request.start.pose)
            goal = pose_from_msg(request.goal.pose)
            poses = checked_path(self.robot, start, goal)
        except (StewartError, ValueError) as exc:
            reject(self, self.diagnostics, "plan_path request", str(exc))
            return response  # empty path = infeasible
        stamp = response.plan.header.stamp
        response.plan.poses = [pose_stamped(p, stamp) for p in poses]
        self.diagnostics.set(OK, "path planned", last_path_waypoints=len(poses))
        return response


def main(args=None) -> None:
    run_node(KinematicsNode, args)


if __name__ == "__main__":
    main()
