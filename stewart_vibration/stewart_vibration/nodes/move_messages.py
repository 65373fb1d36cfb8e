"""The move_to_pose action's messages (stewart_vibration_interfaces/action/MoveToPose) to and from poses and
records, for its clients (the runner, the planning UI)."""

from __future__ import annotations

import numpy as np
from builtin_interfaces.msg import Time as TimeMsg

from stewart_vibration_interfaces.action import MoveToPose

from ..errors import InvalidInputError, MalformedMessageError, RefusedError
from ..messages.fields import BASE_FRAME, check_frame
from .message_conversions import pose_from_msg, pose_stamped
from .outcomes import outcome_name

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
