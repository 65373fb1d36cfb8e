"""A planned path through waypoints (pure): what kinematics/plan_path answers. Nothing moves.

Each segment is a straight SE(3) path (motion.paths.checked_path: 1 mm / 1 deg steps, every sample checked
against the workspace, the strut limits and, under a tissue model, the strut forces); while the force guard is
tripped a segment further in the stopped direction is refused. The path's duration is that of a minimum-jerk
move of the struts per segment at the request's speed scale. One waypoint means a path from the current pose
estimate. Poses (6,) [x, y, z, roll, pitch, yaw] in m and rad in the base frame; times in s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..dynamics.tissue import TissueModel
from ..errors import InvalidInputError, RefusedError, StewartError
from ..kinematics import check_pose
from ..robot import Robot
from .force_guard import ForceGuard
from .move_goal import move_request
from .paths import checked_path
from .profiles import minimum_jerk_duration


class SegmentRefused(RefusedError):
    """A path refused at one of its segments, with the refusal's outcome and text; ``waypoint``: the waypoint the
    failing segment ends at, as the request counts them; ``time_s``: when the path reaches that segment (s)."""

    def __init__(self, error: StewartError, waypoint: int, time_s: float):
        super().__init__(error.outcome, str(error))
        self.waypoint, self.time_s = waypoint, float(time_s)


@dataclass(frozen=True)
class PathPlan:
    """The checked samples [n, 6] of a path (the first the start, the last the final waypoint) and its duration
    (s)."""

    samples: np.ndarray
    duration: float


def path_waypoints(waypoints: list, current_pose) -> tuple[list[np.ndarray], int]:
    """The poses a path goes through and how many were put before the request's (1: the current pose estimate,
    for a request of one waypoint; else 0). Raises InvalidInputError without a waypoint, RefusedError NOT_READY
    for one waypoint and no estimate (``current_pose`` None)."""
    if not waypoints:
        raise InvalidInputError("plan_path needs at least one waypoint (one: from the current pose estimate)")
    if len(waypoints) > 1:
        return list(waypoints), 0
    if current_pose is None:
        raise RefusedError("NOT_READY", "one waypoint and no pose estimate yet to start the path from")
    return [np.array(current_pose, float)] + list(waypoints), 1


def plan_path(robot: Robot, poses: list, offset: int, speed_scale: float, default_speed_scale: float,
              min_duration: float, guard: ForceGuard, tissue: TissueModel | None = None) -> PathPlan:
    """The checked path through ``poses`` (from ``path_waypoints``, ``offset`` of them added before the
    request's) at ``speed_scale`` (0: ``default_speed_scale``), each segment's move at least ``min_duration``
    long. Raises InvalidInputError for a speed scale out of its range, else SegmentRefused for the first
    segment the guard or the checks refuse."""
    speed_scale = move_request(poses[-1], speed_scale, 0.0, 0.0, default_speed_scale, 0.0, 0.0).speed_scale
    speed = robot.limits.strut_velocity_max * speed_scale
    samples: list = []
    duration = 0.0
    for i in range(len(poses) - 1):
        try:
            guard.check_target(poses[i], poses[i + 1])
            segment = checked_path(robot, poses[i], poses[i + 1], tissue=tissue)
        except StewartError as exc:
            raise SegmentRefused(exc, i + 1 - offset, duration) from exc
        lengths = check_pose(robot, np.array([poses[i], poses[i + 1]]))
        duration += minimum_jerk_duration(lengths[0], lengths[1], speed, min_duration)
        samples.extend(segment if i == 0 else segment[1:])
    return PathPlan(np.array(samples), duration)
