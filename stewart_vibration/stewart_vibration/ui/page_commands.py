"""The planning page's commands checked and answered (pure): the answers to a pose check, a path, a move, a
preview, a start and a stop, from the core's checks and the suite's answers. Poses of the platform frame in the
base frame, m and rad (the page's fields: mm and deg)."""

from __future__ import annotations

import numpy as np

from ..robot import Robot
from . import model
from .command_queue import refusal
from .move_follow import FollowedMove
from .planner_settings import PlannerSettings


def check_pose_answer(robot: Robot, fields: dict) -> dict:
    """Is the pose the page entered reachable, and with what margins (model.reachability)."""
    result = model.reachability(robot, model.pose_from_fields(fields))
    return {"ok": True, "message": "reachable" if result["reachable"] else result["error"]["message"], **result}


def path_answer(robot: Robot, outcome: str, message: str, poses) -> dict:
    """kinematics/plan_path's answer: its outcome name and message, the path's poses [n, 6] when it SUCCEEDED."""
    if outcome == "SUCCEEDED":
        return {"ok": True, "message": f"path of {len(poses)} waypoints",
                "path": model.path_margins(robot, np.array(poses))}
    return {"ok": False, "refused_by": "kinematics", "outcome": outcome, "message": f"{outcome}: {message}",
            "path": {"waypoints": 0}}


def move_refused(check: dict, node_reason: str | None) -> dict:
    """A move refused here (nothing was sent) by its reachability ``check``, beside the kinematics node's own
    reason (``node_reason``, from a plan_path that moves nothing)."""
    error = check["error"]
    return {"ok": False, "refused_by": "planning_ui (core check_pose)", "error": error,
            "message": f"not sent: {error['type']}: {error['message']}", "node_reason": node_reason, "check": check}


def move_sent(action: str, check: dict) -> dict:
    """The answer to a move sent as a goal of ``action``, with its reachability ``check``."""
    return {"ok": True, "message": f"move goal sent to kinematics ({action}); following the move", "check": check}


def preview_answer(robot: Robot, pose, settings: dict, planner: PlannerSettings) -> dict:
    """The preview of a vibration with ``settings`` at ``pose`` (the latest pose estimate)."""
    preview = model.vibration_preview(robot, pose, settings, planner.ranges)
    return {"ok": True, "message": "feasible" if preview["feasible"] else preview["reason"],
            "preview": preview, "planner_settings_known": planner.known}


def start_check(robot: Robot, pose, settings: dict, planner: PlannerSettings, move: FollowedMove | None,
                now: float) -> tuple[dict, dict | None]:
    """(the preview, the refusal or None) of a start at ``pose`` with ``settings`` at ``now`` (monotonic s): no
    start while the page's move is under way (the preview is {} then: none is made), nor one the core's checks
    find infeasible."""
    if move is not None and move.blocks_start(now):
        return {}, refusal("not started: the platform is still moving to its target (start when the move has "
                             "settled)")
    preview = model.vibration_preview(robot, pose, settings, planner.ranges)
    if not preview["feasible"]:
        return preview, {**refusal(f"not started: {preview['reason']}", "planning_ui (core checks)"),
                         "preview": preview}
    return preview, None


def cancel_answer(no_error: bool, canceling: int) -> dict:
    """The answer of a cancel of every vibrate goal: ``no_error`` (CancelGoal's ERROR_NONE), how many cancel."""
    return {"ok": no_error or canceling == 0,
            "message": f"cancelling {canceling} vibration(s): the units ramp out" if canceling else
            "no vibration is running"}
