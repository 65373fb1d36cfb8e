"""kinematics node in its own process over real DDS (issue 5)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from nav_msgs.srv import GetPlan
from ros_client import RosTestClient
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from stewart_vibration import inverse_kinematics, pose_to_position_quaternion
from stewart_vibration.runtime.processes import ros_environment, start_python_module

pytestmark = pytest.mark.integration


@pytest.fixture
def kinematics_node(ros_domain, tmp_path):
    proc = start_python_module(
        "kinematics", "stewart_vibration.nodes.kinematics_node", [], ros_environment(ros_domain), tmp_path
    )
    client = RosTestClient()
    try:
        yield proc, client
    finally:
        client.close()
        code = proc.stop()
        assert code is not None


def pose_msg(pose, quat=None):
    position, q = pose_to_position_quaternion(pose)
    msg = PoseStamped()
    msg.header.frame_id = "base"
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = map(float, position)
    qq = q if quat is None else quat
    msg.pose.orientation.x, msg.pose.orientation.y, msg.pose.orientation.z, msg.pose.orientation.w = map(float, qq)
    return msg


def joint_state(lengths, vib=None):
    msg = JointState()
    msg.name = [f"leg_{i}" for i in range(1, 7)] + [f"vib_{i}" for i in range(1, 7)]
    msg.position = list(map(float, lengths)) + list(map(float, np.zeros(6) if vib is None else vib))
    return msg


def test_pose_estimate_trajectory_and_rejections(robot, kinematics_node):
    proc, client = kinematics_node
    estimates = client.subscribe("platform/pose_estimate", PoseStamped)
    trajectories = client.subscribe("legs/joint_trajectory", JointTrajectory)
    diagnostics = client.subscribe("/diagnostics", DiagnosticArray)
    states = client.publisher("legs/joint_states", JointState)
    targets = client.publisher("platform/target_pose", PoseStamped)
    assert client.wait_for_subscribers("legs/joint_states"), proc.log_text()

    # leg + vib lengths of a known pose -> FK pose estimate
    pose = robot.home_pose + np.array([0.002, -0.001, 0.003, 0.02, -0.01, 0.03])
    lengths = inverse_kinematics(robot, pose)
    vib = np.array([1e-5, -2e-5, 0.0, 3e-5, 0.0, -1e-5])
    states.publish(joint_state(lengths - vib, vib))
    assert client.spin_until(lambda: len(estimates) > 0, 20), proc.log_text()
    est = estimates[-1].pose
    assert math.isclose(est.position.x, pose[0], abs_tol=1e-10)
    assert math.isclose(est.position.z, pose[2], abs_tol=1e-10)

    # a reachable target -> one minimum-jerk trajectory ending at the IK lengths
    target = robot.home_pose + np.array([0.005, 0.0, -0.004, 0.0, 0.05, 0.0])
    targets.publish(pose_msg(target))
    assert client.spin_until(lambda: len(trajectories) > 0, 20), proc.log_text()
    traj = trajectories[-1]
    assert traj.joint_names == [f"leg_{i}" for i in range(1, 7)]
    assert np.allclose(traj.points[-1].positions, inverse_kinematics(robot, target), atol=1e-12)
    times = [p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in traj.points]
    assert np.all(np.diff(times) > 0)
    speeds = np.abs([p.velocities for p in traj.points]).max()
    assert speeds <= robot.limits.strut_velocity_max + 1e-12
    assert np.allclose(traj.points[-1].velocities, 0, atol=1e-12)

    # bad targets: NaN, non-unit quaternion, unreachable -> nothing sent, reason on /diagnostics
    sent = len(trajectories)
    nan_msg = pose_msg(target)
    nan_msg.pose.position.x = float("nan")
    targets.publish(nan_msg)
    targets.publish(pose_msg(target, quat=[0, 0, 0, 2.0]))
    unreachable = robot.home_pose + np.array([0, 0, 0.2, 0, 0, 0])
    targets.publish(pose_msg(unreachable))
    world = pose_msg(target)
    world.header.frame_id = "world"  # a pose in another frame is refused, not read as base
    targets.publish(world)

    def reasons():  # anywhere in the message: a "stale: ..." prefix precedes it once the one joint state is old
        return [s.message for a in diagnostics for s in a.status if "rejected target pose" in s.message]

    kinds = ("non-finite", "unit quaternion", "stroke limit", "'world'")  # each of the four, by its content
    assert client.spin_until(lambda: all(k in " | ".join(reasons()) for k in kinds), 20), (reasons(), proc.log_text())
    client.spin_for(0.3)
    assert len(trajectories) == sent

    # a target while the move is pending or under way is refused: this test's only clock is the states' stamps, so
    # a state stamped after the move's end (at its goal) ends it
    targets.publish(pose_msg(robot.home_pose))
    assert client.spin_until(lambda: "a move is under way" in " | ".join(reasons()), 20), (reasons(), proc.log_text())
    ended = joint_state(inverse_kinematics(robot, target))
    ended.header.stamp.sec = 10
    count = len(estimates)
    states.publish(ended)
    assert client.spin_until(lambda: len(estimates) > count, 20), proc.log_text()

    # hand-typed quaternions (the README's example: norm 1.00004) are normalised and accepted, also in an
    # empty frame (documented as base)
    typed = pose_msg(target, quat=[0.0, 0.025, 0.0, 1.00003])
    typed.header.frame_id = ""
    targets.publish(typed)
    assert client.spin_until(lambda: len(trajectories) > sent, 20), (reasons(), proc.log_text())
    assert proc.alive()


def test_plan_path_service(robot, kinematics_node):
    proc, client = kinematics_node
    request = GetPlan.Request()
    request.start = pose_msg(robot.home_pose)
    request.goal = pose_msg(robot.home_pose + np.array([0.01, 0, 0, 0, 0, 0.1]))
    response = client.call(GetPlan, "kinematics/plan_path", request)
    assert len(response.plan.poses) >= 11
    last = response.plan.poses[-1].pose.position
    assert math.isclose(last.x, 0.01, abs_tol=1e-12)
    diagnostics = client.subscribe("/diagnostics", DiagnosticArray)
    request.goal = pose_msg(robot.home_pose + np.array([0.0, 0.0, 0.2, 0, 0, 0]))
    assert len(client.call(GetPlan, "kinematics/plan_path", request).plan.poses) == 0
    assert client.spin_until(lambda: any("plan_path" in s.message and "StrokeLimitError" in s.message
                                         for a in diagnostics for s in a.status), 10)  # the reason is visible

    # goal only, as the README calls it: from the current pose estimate (not from the origin)
    states = client.publisher("legs/joint_states", JointState)
    current = robot.home_pose + np.array([0.003, 0.0, 0.0, 0.0, 0.0, 0.0])
    estimates = client.subscribe("platform/pose_estimate", PoseStamped)
    assert client.wait_for_subscribers("legs/joint_states")
    states.publish(joint_state(inverse_kinematics(robot, current)))
    assert client.spin_until(lambda: estimates, 10)
    goal_only = GetPlan.Request()
    goal_only.goal.header.frame_id = "base"
    goal_only.goal.pose.position.z = 0.165
    goal_only.goal.pose.orientation.w = 1.0
    plan = client.call(GetPlan, "kinematics/plan_path", goal_only).plan.poses
    assert len(plan) > 2
    first = plan[0].pose.position
    assert math.isclose(first.x, 0.003, abs_tol=1e-9) and math.isclose(plan[-1].pose.position.z, 0.165, abs_tol=1e-12)
    assert proc.alive()
