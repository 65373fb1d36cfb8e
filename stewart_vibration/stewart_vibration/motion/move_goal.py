"""A reduction move as an action goal (pure): the goal's checks, and when and how the move ends.

The kinematics node turns a MoveToPose goal into a ``MoveRequest`` (``move_request``: every value checked,
0 meaning the node's default, a goal's limits no higher than the node's) and follows the move with a
``MoveWatch``: it is told what the robot does (``moving``: a trajectory that ends at a time; ``stopping``: a
stop of the guard, of a cancel or of a pause for late estimates; ``end``: the robot stopped or refused it)
and ``update`` says when the goal is over and with which outcome. Times in s of the robot's clock; poses
(6,) [x, y, z, roll, pitch, yaw] (m, rad) in the base frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError
from ..kinematics.rotations import rotation_from_rpy, so3_log

SETTLE_S = 0.1  # the robot's time after a move's or a stop's planned end before the goal's outcome is judged
MIN_SPEED_SCALE = 0.01  # the slowest move (fraction of strut_velocity_max): slower ones would last for hours


@dataclass(frozen=True)
class MoveRequest:
    """A checked move goal: the target pose (6,), the speed scale (fraction of strut_velocity_max,
    [MIN_SPEED_SCALE, 1]) and
    the force guard's limits for this move (N, N m; 0 = off)."""

    target: np.ndarray
    speed_scale: float
    force_limit: float
    moment_limit: float

    @property
    def guarded(self) -> bool:
        """Whether the force guard watches this move (a force or a moment limit is on)."""
        return self.force_limit > 0 or self.moment_limit > 0


def move_request(target, speed_scale: float, force_limit: float, moment_limit: float, default_speed_scale: float,
                 guard_force: float, guard_moment: float) -> MoveRequest:
    """The MoveRequest of a goal's values. ``speed_scale`` 0 = ``default_speed_scale``; a limit of 0 = the
    node's (``guard_force`` N, ``guard_moment`` N m, 0 = off); a goal may lower a limit, not raise it (with
    the node's off it may set one). Raises InvalidInputError naming the value."""
    values = {"speed_scale": speed_scale, "force_limit_n": force_limit, "moment_limit_nm": moment_limit}
    for name, value in values.items():
        if not np.isfinite(value):
            raise InvalidInputError(f"{name} {value} is not finite")
    if speed_scale != 0.0 and not MIN_SPEED_SCALE <= speed_scale <= 1.0:
        raise InvalidInputError(f"speed_scale {speed_scale:g} is outside [{MIN_SPEED_SCALE:g}, 1] (0 = the node's "
                                "speed_scale)")
    limits = []
    for name, value, node_limit, parameter in (("force_limit_n", force_limit, guard_force, "guard_force_n"),
                                               ("moment_limit_nm", moment_limit, guard_moment, "guard_moment_nm")):
        if value < 0:
            raise InvalidInputError(f"{name} {value:g} is negative (0 = the node's {parameter})")
        if value > 0 and 0 < node_limit < value:
            raise InvalidInputError(f"{name} {value:g} is above the node's {parameter} {node_limit:g}: a goal may "
                                    "only lower the force guard's limits")
        limits.append(value if value > 0 else node_limit)
    return MoveRequest(np.asarray(target, float).copy(), float(speed_scale or default_speed_scale), limits[0],
                       limits[1])


def pose_errors(pose, target) -> tuple[float, float]:
    """(|p_target - p| (m), rotation angle from ``pose`` to ``target`` (rad)) of two poses (6,)."""
    pose, target = np.asarray(pose, float), np.asarray(target, float)
    angle = np.linalg.norm(so3_log(rotation_from_rpy(target[3:]) @ rotation_from_rpy(pose[3:]).T))
    return float(np.linalg.norm(target[:3] - pose[:3])), float(angle)


@dataclass(frozen=True)
class MoveEnd:
    """How a move goal ended: an outcome name of the outcome table and a sentence for people."""

    outcome: str
    message: str


class MoveWatch:
    """Follows one move goal to its outcome (see the module docstring). ``start_pose`` and ``target`` (6,);
    ``position_tolerance`` (m) and ``angle_tolerance`` (rad): how close the pose estimate must come to the
    target for SUCCEEDED; ``goal_time`` (s): how long after the planned end it may take to get there (then
    TIMEOUT); ``pause_timeout`` (s): how long a pause for late estimates may last (then TIMEOUT)."""

    def __init__(self, start_pose, target, position_tolerance: float, angle_tolerance: float, goal_time: float,
                 pause_timeout: float):
        self.start_pose, self.target = np.asarray(start_pose, float).copy(), np.asarray(target, float).copy()
        self.position_tolerance, self.angle_tolerance = float(position_tolerance), float(angle_tolerance)
        self.goal_time, self.pause_timeout = float(goal_time), float(pause_timeout)
        self.phase = "moving"  # moving | stopping
        self.why = ""  # while stopping: GUARD_STOPPED, CANCELED or PAUSED
        self.why_message = ""
        self.until = np.inf  # the planned end of the move or the stop (s)
        self.since = np.nan  # when the current stop began (s)
        self.ended: MoveEnd | None = None
        self._start_distance = max(pose_errors(start_pose, target)[0], 1e-12)

    def moving(self, end_time: float) -> None:
        """The robot runs a trajectory to the target that ends at ``end_time`` (s): a new one (a resumed move)
        or a calibrated end of the same."""
        self.phase, self.why, self.until = "moving", "", float(end_time)

    def stopping(self, why: str, end_time: float, now: float, message: str = "") -> None:
        """A stop short of the target that ends at ``end_time`` (s), begun at ``now``: ``why`` GUARD_STOPPED
        (the force guard), CANCELED (the client) or PAUSED (late estimates: the move may resume). A guard stop
        outranks a cancel (the client learns that the load reached a limit)."""
        if self.phase == "stopping" and self.why == "GUARD_STOPPED" and why != "GUARD_STOPPED":
            return
        self.phase, self.why, self.why_message, self.until, self.since = "stopping", why, message, float(end_time), \
            float(now)

    def end(self, outcome: str, message: str) -> None:
        """The goal is over now (the robot stopped, refused the move, a defect): the first end counts."""
        if self.ended is None:
            self.ended = MoveEnd(outcome, message)

    def progress(self, pose) -> float:
        """The move's progress at ``pose``: 0 at the start, 1 at the target (by the distance to it)."""
        return float(np.clip(1.0 - pose_errors(pose, self.target)[0] / self._start_distance, 0.0, 1.0))

    def time_remaining(self, now: float) -> float:
        """s of the robot's clock until the planned end of the move or of the stop (0 once past it)."""
        return float(max(self.until - now, 0.0)) if np.isfinite(self.until) else 0.0

    def update(self, now: float, pose) -> MoveEnd | None:
        """The goal's end at ``now`` (s) with the pose estimate ``pose`` (6,), or None while it goes on."""
        if self.ended is not None:
            return self.ended
        paused = self.phase == "stopping" and self.why == "PAUSED"
        if paused and now - self.since > self.pause_timeout:
            self.end("TIMEOUT", f"the move paused for late external-wrench estimates for more than "
                     f"{self.pause_timeout:g} s; the robot holds where the pause stopped it")
        if paused or now < self.until + SETTLE_S:
            return self.ended
        position, angle = pose_errors(pose, self.target)
        figures = f"{position * 1e6:.1f} um and {np.degrees(angle):.4f} deg from the target"
        if self.phase == "stopping":
            self.end(self.why, f"{self.why_message}; at rest {figures}" if self.why_message else
                     f"stopped at rest {figures}")
            return self.ended
        if position <= self.position_tolerance and angle <= self.angle_tolerance:
            self.end("SUCCEEDED", f"at the target: {figures}")
        elif now >= self.until + self.goal_time:
            self.end("TIMEOUT", f"not within the goal tolerance ({self.position_tolerance * 1e6:g} um, "
                     f"{np.degrees(self.angle_tolerance):g} deg) {self.goal_time:g} s after the move's end: {figures}")
        return self.ended

