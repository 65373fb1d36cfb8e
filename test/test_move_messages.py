"""The kinematics node's move and path messages built from the core's values, without a running ROS graph
(nodes.move_messages, nodes.message_conversions.leg_trajectory_msg): every field against the value it carries."""

from __future__ import annotations

import math

import numpy as np
from geometry_msgs.msg import Pose

from stewart_vibration.errors import InvalidInputError, StrokeLimitError
from stewart_vibration.kinematics.rotations import pose_from_position_quaternion
from stewart_vibration.messages.outcome_codes import outcome_name
from stewart_vibration.motion.goal_keeper import MoveFeedback, MoveSummary
from stewart_vibration.motion.path_plan import PathPlan, SegmentRefused
from stewart_vibration.nodes.message_conversions import leg_trajectory_msg, time_message
from stewart_vibration.nodes.move_messages import move_feedback_msg, move_result_msg, path_msg, path_refusal_msg
from stewart_vibration_interfaces.srv import PlanPath

POSE = np.array([0.001, -0.002, 0.161, 0.01, -0.02, 0.03])


def pose_of(msg) -> np.ndarray:
    p, q = msg.position, msg.orientation
    return pose_from_position_quaternion([p.x, p.y, p.z], [q.x, q.y, q.z, q.w])


def test_a_leg_trajectory_carries_its_points_from_stamp_zero():
    times = [0.5, 1.0000000004]
    positions = np.array([[0.17] * 6, [0.18] * 6])
    msg = leg_trajectory_msg(times, positions, positions * 0.1, positions * 0.01)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (0, 0)
    assert msg.joint_names == [f"leg_{i}" for i in range(1, 7)] and len(msg.points) == 2
    assert (msg.points[1].time_from_start.sec, msg.points[1].time_from_start.nanosec) == (1, 0)  # to the ns
    assert list(msg.points[0].positions) == [0.17] * 6 and list(msg.points[1].velocities) == [0.018] * 6
    assert list(msg.points[1].accelerations) == [0.0018] * 6


def test_feedback_and_result_carry_the_goals_values():
    feedback = move_feedback_msg(MoveFeedback(0.25, 1.5, POSE, np.array([1.0, 2.0, 3.0, 0.1, 0.2, 0.3]), 40.0,
                                              float("nan"), 1))
    assert (feedback.progress, feedback.time_remaining_s, feedback.guard_state) == (0.25, 1.5, 1)
    assert feedback.predicted_force_n == 40.0 and math.isnan(feedback.predicted_moment_nm)
    load = feedback.measured_load
    assert [load.force.x, load.force.y, load.force.z, load.torque.x, load.torque.y, load.torque.z] == \
        [1.0, 2.0, 3.0, 0.1, 0.2, 0.3]
    np.testing.assert_allclose(pose_of(feedback.pose_estimate), POSE, atol=1e-12)
    result = move_result_msg(MoveSummary("GUARD_STOPPED", "force guard tripped", POSE, 2e-3, 0.01, 210.0, 3.0, 4.5))
    assert outcome_name(result.outcome.code) == "GUARD_STOPPED" and result.outcome.message == "force guard tripped"
    assert (result.position_error_m, result.angle_error_rad, result.peak_force_n, result.peak_moment_nm,
            result.duration_s) == (2e-3, 0.01, 210.0, 3.0, 4.5)
    np.testing.assert_allclose(pose_of(result.final_pose), POSE, atol=1e-12)
    refused = move_result_msg(MoveSummary("NOT_READY", "no states"))
    assert outcome_name(refused.outcome.code) == "NOT_READY" and refused.final_pose == Pose()  # no estimate: unset


def test_a_path_answer_has_its_samples_or_its_refusal_with_the_failing_waypoint():
    stamp = time_message(12.5)
    samples = np.array([POSE, POSE + [0.001, 0, 0, 0, 0, 0]])
    answer = path_msg(PlanPath.Response(), PathPlan(samples, 0.75), 2, stamp)
    assert outcome_name(answer.outcome.code) == "SUCCEEDED" and "2 samples through 2 waypoints over 0.75 s" in \
        answer.outcome.message
    assert answer.path.header.frame_id == "base" and answer.path.header.stamp == stamp
    assert answer.duration_s == 0.75 and (answer.failing_waypoint, math.isnan(answer.failing_time_s)) == (-1, True)
    np.testing.assert_allclose([pose_of(p.pose) for p in answer.path.poses], samples, atol=1e-12)
    assert all(p.header.stamp == stamp and p.header.frame_id == "base" for p in answer.path.poses)
    segment = path_refusal_msg(PlanPath.Response(), SegmentRefused(StrokeLimitError("leg_3 beyond the stroke"), 2,
                                                                   1.25), stamp)
    assert outcome_name(segment.outcome.code) == "UNREACHABLE_POSE" and "leg_3" in segment.outcome.message
    assert (segment.failing_waypoint, segment.failing_time_s, len(segment.path.poses)) == (2, 1.25, 0)
    whole = path_refusal_msg(PlanPath.Response(), InvalidInputError("no waypoint"), stamp)
    assert outcome_name(whole.outcome.code) == "INVALID_ARGUMENT"
    assert (whole.failing_waypoint, math.isnan(whole.failing_time_s)) == (-1, True)
