"""The move_to_pose action's messages (stewart_vibration_interfaces/action/MoveToPose) to and from poses and
records: for its clients (the runner, the planning UI) and for the kinematics node (a goal's feedback and
result from motion.goal_keeper's values); and the kinematics/plan_path service's answer (PlanPath)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from builtin_interfaces.msg import Time as TimeMsg
from geometry_msgs.msg import Wrench
from nav_msgs.msg import Path

from stewart_vibration_interfaces.action import MoveToPose
from stewart_vibration_interfaces.srv import PlanPath

from ..errors import InvalidInputError, MalformedMessageError, RefusedError, StewartError
from ..messages.fields import BASE_FRAME, check_frame
from ..motion.path_plan import SegmentRefused
from .message_conversions import pose_from_msg, pose_stamped
from .outcomes import outcome, outcome_name, outcome_of

if TYPE_CHECKING:  # the values' types only: the action's clients need none of the goal keeping
    from ..motion.goal_keeper import MoveFeedback, MoveSummary
    from ..motion.path_plan import PathPlan

MOVE_ACTION = "kinematics/move_to_pose"


def move_goal(pose, speed_scale: float = 0.0, force_limit_n: float = 0.0, moment_limit_nm: float = 0.0,
              frame: str = BASE_FRAME) -> MoveToPose.Goal:
    """A MoveToPose goal to ``pose`` (6,) [x, y, z, roll, pitch, yaw] (m, rad) in ``frame``; 0 = the node's
    speed scale and guard limits."""
    goal = MoveToPose.Goal(speed_scale=float(speed_scale), force_limit_n=float(force_limit_n),
                           moment_limit_nm=float(moment_limit_nm))
    goal.target = pose_stamped(np.asarray(pose, float), TimeMsg(), frame)
    return goal


def base_pose(msg, what: str) -> np.ndarray:
    """The pose (6,) of a geometry_msgs/PoseStamped a client asks to go to (``what`` names it in refusals):
    RefusedError UNKNOWN_FRAME unless in the base frame (or ""); InvalidInputError for a pose that is not one
    (quaternion normalised within 1e-3)."""
    try:
        check_frame(msg.header.frame_id, what)
    except MalformedMessageError as exc:
        raise RefusedError("UNKNOWN_FRAME", str(exc)) from None
    return pose_from_msg(msg.pose)


def move_feedback_msg(feedback: MoveFeedback) -> MoveToPose.Feedback:
    """A running goal's MoveToPose feedback: progress, time left (s), the pose estimate, the measured load
    (N, N m), the predicted load at a stop's end and the guard's state."""
    msg = MoveToPose.Feedback(progress=feedback.progress, time_remaining_s=feedback.time_remaining,
                              predicted_force_n=feedback.predicted_force,
                              predicted_moment_nm=feedback.predicted_moment, guard_state=feedback.guard_state)
    msg.pose_estimate = pose_stamped(feedback.pose, TimeMsg()).pose
    msg.measured_load = Wrench()
    load = [float(v) for v in feedback.load]
    msg.measured_load.force.x, msg.measured_load.force.y, msg.measured_load.force.z = load[:3]
    msg.measured_load.torque.x, msg.measured_load.torque.y, msg.measured_load.torque.z = load[3:]
    return msg


def move_result_msg(summary: MoveSummary) -> MoveToPose.Result:
    """A goal's MoveToPose result: its outcome, duration and peak load, and with a pose estimate the final pose
    and its residual error to the target."""
    result = MoveToPose.Result(outcome=outcome(summary.outcome, summary.message), duration_s=summary.duration,
                               peak_force_n=summary.peak_force, peak_moment_nm=summary.peak_moment)
    if summary.final_pose is not None:
        result.final_pose = pose_stamped(summary.final_pose, TimeMsg()).pose
        result.position_error_m, result.angle_error_rad = summary.position_error, summary.angle_error
    return result


def path_msg(response: PlanPath.Response, plan: PathPlan, waypoints: int, stamp) -> PlanPath.Response:
    """kinematics/plan_path's answer with ``plan`` (through ``waypoints`` waypoints): the path's samples as
    poses in base stamped ``stamp`` (builtin_interfaces/Time), its duration and SUCCEEDED."""
    _path_header(response, stamp)
    response.path.poses = [pose_stamped(pose, stamp) for pose in plan.samples]
    response.duration_s = plan.duration
    response.outcome = outcome("SUCCEEDED", f"path of {len(plan.samples)} samples through {waypoints} waypoints "
                               f"over {plan.duration:.2f} s")
    return response


def path_refusal_msg(response: PlanPath.Response, refusal: StewartError, stamp) -> PlanPath.Response:
    """kinematics/plan_path's answer to a refused request: the refusal's code and text, an empty path stamped
    ``stamp`` and, when a segment failed (SegmentRefused), the failing waypoint and the time along the path
    where it fails (else -1 and NaN)."""
    _path_header(response, stamp)
    if isinstance(refusal, SegmentRefused):
        response.failing_waypoint, response.failing_time_s = refusal.waypoint, refusal.time_s
    response.outcome = outcome_of(refusal)
    return response


def _path_header(response: PlanPath.Response, stamp) -> None:
    response.path = Path()
    response.path.header.frame_id, response.path.header.stamp = BASE_FRAME, stamp
    response.failing_waypoint, response.failing_time_s = -1, float("nan")


def move_result_record(result: MoveToPose.Result) -> dict:
    """A MoveToPose result as plain values (outcome name and message, SI units, the final pose (6,) as a list)."""
    return {"outcome": outcome_name(result.outcome.code), "message": result.outcome.message,
            "final_pose": _pose_or_none(result.final_pose),
            "position_error_m": float(result.position_error_m), "angle_error_rad": float(result.angle_error_rad),
            "peak_force_n": float(result.peak_force_n), "peak_moment_nm": float(result.peak_moment_nm),
            "duration_s": float(result.duration_s)}


def _pose_or_none(msg) -> list | None:
    try:
        return pose_from_msg(msg).tolist()
    except InvalidInputError:  # left unset: the goal was refused before this node had a pose estimate
        return None
