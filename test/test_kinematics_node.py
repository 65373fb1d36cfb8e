"""kinematics node in its own process over real DDS."""

from __future__ import annotations

import math

import numpy as np
import pytest
from geometry_msgs.msg import PoseStamped
from ros_client import RosTestClient
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from stewart_vibration import inverse_kinematics, pose_to_position_quaternion
from stewart_vibration.nodes.move_messages import MOVE_ACTION
from stewart_vibration.nodes.outcomes import outcome_name
from stewart_vibration.runtime.processes import ros_environment, start_python_module
from stewart_vibration_interfaces.action import MoveToPose
from stewart_vibration_interfaces.srv import PlanPath

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


def stamped_state(lengths, seconds: int):
    msg = joint_state(lengths)
    msg.header.stamp.sec = seconds
    return msg


def publish_at_rest(states, lengths, t0_s: float, vib=None, duration_s: float = 0.3, rate_hz: float = 500.0):
    """States still at ``lengths`` stamped from ``t0_s`` over ``duration_s`` (the robot's clock): enough for
    kinematics to judge the struts at rest (a move is planned from rest)."""
    for k in range(int(duration_s * rate_hz) + 1):
        msg = joint_state(lengths, vib)
        stamp = t0_s + k / rate_hz
        msg.header.stamp.sec, msg.header.stamp.nanosec = int(stamp), int(round((stamp % 1.0) * 1e9)) % 1_000_000_000
        states.publish(msg)


def test_pose_estimate_move_goal_and_its_refusals(robot, kinematics_node):
    proc, client = kinematics_node
    estimates = client.subscribe("platform/pose_estimate", PoseStamped)
    trajectories = client.subscribe("legs/joint_trajectory", JointTrajectory)
    states = client.publisher("legs/joint_states", JointState, depth=500)  # bursts of states at rest
    assert client.wait_for_subscribers("legs/joint_states"), proc.log_text()

    # leg + vib lengths of a known pose -> FK pose estimate
    pose = robot.home_pose + np.array([0.002, -0.001, 0.003, 0.02, -0.01, 0.03])
    lengths = inverse_kinematics(robot, pose)
    vib = np.array([1e-5, -2e-5, 0.0, 3e-5, 0.0, -1e-5])
    publish_at_rest(states, lengths - vib, 0.0, vib)
    assert client.spin_until(lambda: len(estimates) > 0, 20), proc.log_text()
    client.spin_for(0.5)  # the rest of the states
    est = estimates[-1].pose
    assert math.isclose(est.position.x, pose[0], abs_tol=1e-10)
    assert math.isclose(est.position.z, pose[2], abs_tol=1e-10)

    # a reachable target -> one minimum-jerk trajectory ending at the IK lengths
    target = robot.home_pose + np.array([0.005, 0.0, -0.004, 0.0, 0.05, 0.0])
    move = client.move(target)
    assert client.spin_until(lambda: len(trajectories) > 0, 20), proc.log_text()
    traj = trajectories[-1]
    assert traj.joint_names == [f"leg_{i}" for i in range(1, 7)]
    assert np.allclose(traj.points[-1].positions, inverse_kinematics(robot, target), atol=1e-12)
    times = [p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in traj.points]
    assert np.all(np.diff(times) > 0)
    speeds = np.abs([p.velocities for p in traj.points]).max()
    assert speeds <= robot.limits.strut_velocity_max + 1e-12
    assert np.allclose(traj.points[-1].velocities, 0, atol=1e-12)

    # a second goal while the move is pending or under way: BUSY, nothing sent
    sent = len(trajectories)
    assert client.move(robot.home_pose).outcome()[0] == "BUSY"

    # this test's only clock is the states' stamps: a state stamped after the move's end, at its goal, ends it
    # SUCCEEDED with the residual error of that state (0 here) against the target
    publish_at_rest(states, inverse_kinematics(robot, target), 10.0)
    name, message = move.outcome()
    assert name == "SUCCEEDED", message
    result = move.result()
    assert result.position_error_m < 1e-9 and result.angle_error_rad < 1e-9, result
    assert math.isclose(result.final_pose.position.x, target[0], abs_tol=1e-9)
    assert move.status() == 4  # action_msgs/GoalStatus SUCCEEDED
    # feedback and result travel on separate topics: the feedback sent before the result may arrive after it
    assert client.spin_until(lambda: len(move.feedback) > 0, 10), proc.log_text()
    assert 0.0 <= move.feedback[-1].feedback.progress <= 1.0

    # bad goals: each refused with its code, nothing sent
    def goal_of(msg, **values):
        goal = MoveToPose.Goal(target=msg, **values)
        return client.send_goal(MOVE_ACTION, goal)

    nan_msg = pose_msg(target)
    nan_msg.pose.position.x = float("nan")
    world = pose_msg(target)
    world.header.frame_id = "world"  # a pose in another frame is refused, not read as base
    cases = [
        (goal_of(nan_msg), "INVALID_ARGUMENT", "finite"),
        (goal_of(pose_msg(target, quat=[0, 0, 0, 2.0])), "INVALID_ARGUMENT", "unit quaternion"),
        (goal_of(pose_msg(robot.home_pose + np.array([0, 0, 0.2, 0, 0, 0]))), "UNREACHABLE_POSE", "stroke"),
        (goal_of(world), "UNKNOWN_FRAME", "'world'"),
        (goal_of(pose_msg(robot.home_pose), speed_scale=2.0), "INVALID_ARGUMENT", "speed_scale"),
        (goal_of(pose_msg(robot.home_pose), force_limit_n=1e4), "INVALID_ARGUMENT", "guard_force_n"),
        (goal_of(pose_msg(robot.home_pose), moment_limit_nm=-1.0), "INVALID_ARGUMENT", "negative"),
    ]
    for goal, code, words in cases:
        name, message = goal.outcome()
        assert (name, words in message) == (code, True), (code, words, message)
        assert goal.status() == 6  # ABORTED
    client.spin_for(0.3)
    assert len(trajectories) == sent

    # hand-typed quaternions (docs/planning-ui.md's example: norm 1.00004) are normalised and accepted, also in an
    # empty frame (documented as base)
    typed = pose_msg(robot.home_pose, quat=[0.0, 0.025, 0.0, 1.00003])
    typed.header.frame_id = ""
    typed_goal = goal_of(typed)
    assert client.spin_until(lambda: len(trajectories) > sent, 20), proc.log_text()
    typed_goal.cancel()  # a stop along the path; the states' stamps are the clock: one at rest, later, ends it
    stop = None if not client.spin_until(lambda: len(trajectories[-1].points) == 1, 10) else trajectories[-1]
    assert stop is not None, "a cancel sends a one-point stop"
    states.publish(stamped_state(stop.points[0].positions, 20))
    assert typed_goal.outcome()[0] == "CANCELED"
    assert typed_goal.status() == 5  # CANCELED
    assert proc.alive()


def test_plan_path_service(robot, kinematics_node):
    proc, client = kinematics_node
    start, goal = robot.home_pose, robot.home_pose + np.array([0.01, 0, 0, 0, 0, 0.1])
    response = client.call(PlanPath, "kinematics/plan_path", PlanPath.Request(waypoints=[pose_msg(start),
                                                                                          pose_msg(goal)]))
    assert outcome_name(response.outcome.code) == "SUCCEEDED", response.outcome
    assert len(response.path.poses) >= 11 and response.failing_waypoint == -1 and response.duration_s > 0.5
    last = response.path.poses[-1].pose.position
    assert math.isclose(last.x, 0.01, abs_tol=1e-12)

    # through three waypoints, the second segment out of the stroke: refused with its code and the waypoint
    beyond = robot.home_pose + np.array([0.0, 0.0, 0.2, 0, 0, 0])
    refused = client.call(PlanPath, "kinematics/plan_path", PlanPath.Request(
        waypoints=[pose_msg(start), pose_msg(goal), pose_msg(beyond)]))
    assert outcome_name(refused.outcome.code) == "UNREACHABLE_POSE" and "stroke" in refused.outcome.message
    assert refused.failing_waypoint == 2 and refused.failing_time_s == pytest.approx(response.duration_s)
    assert not refused.path.poses
    world = pose_msg(goal)
    world.header.frame_id = "world"
    odd = client.call(PlanPath, "kinematics/plan_path", PlanPath.Request(waypoints=[pose_msg(start), world]))
    assert outcome_name(odd.outcome.code) == "UNKNOWN_FRAME"
    none = client.call(PlanPath, "kinematics/plan_path", PlanPath.Request())
    assert outcome_name(none.outcome.code) == "INVALID_ARGUMENT"
    # one waypoint before any state: nothing to start from
    alone = client.call(PlanPath, "kinematics/plan_path", PlanPath.Request(waypoints=[pose_msg(goal)]))
    assert outcome_name(alone.outcome.code) == "NOT_READY"

    # one waypoint, as docs/planning-ui.md calls it: from the current pose estimate (not from the origin)
    states = client.publisher("legs/joint_states", JointState)
    current = robot.home_pose + np.array([0.003, 0.0, 0.0, 0.0, 0.0, 0.0])
    estimates = client.subscribe("platform/pose_estimate", PoseStamped)
    assert client.wait_for_subscribers("legs/joint_states")
    states.publish(joint_state(inverse_kinematics(robot, current)))
    assert client.spin_until(lambda: estimates, 10)
    target = PoseStamped()
    target.header.frame_id = "base"
    target.pose.position.z = 0.165
    target.pose.orientation.w = 1.0
    plan = client.call(PlanPath, "kinematics/plan_path", PlanPath.Request(waypoints=[target])).path.poses
    assert len(plan) > 2
    first = plan[0].pose.position
    assert math.isclose(first.x, 0.003, abs_tol=1e-9) and math.isclose(plan[-1].pose.position.z, 0.165, abs_tol=1e-12)
    assert proc.alive()
