"""Smooth point-to-point motion: minimum-jerk leg trajectories and SE(3) paths.

Minimum jerk (Flash and Hogan 1985): with s = t / T in [0, 1],
x(t) = x0 + (x1 - x0) (10 s^3 - 15 s^4 + 6 s^5); zero velocity and
acceleration at both ends; peak speed 1.875 |x1 - x0| / T at s = 1/2,
peak acceleration 5.7735 |x1 - x0| / T^2 at s = 0.5 -+ sqrt(3)/6.
"""

from __future__ import annotations

import numpy as np

from .errors import InvalidInputError
from .kinematics import check_pose
from .robot import Robot
from .rotations import rotation_from_rpy, rpy_from_rotation, so3_exp, so3_log
from .validation import as_batch

MIN_JERK_PEAK_SPEED = 1.875  # max of d/ds (10 s^3 - 15 s^4 + 6 s^5)


def minimum_jerk(start, goal, duration: float, times):
    """(positions, velocities, accelerations) [n, dim] of a minimum-jerk move.

    start, goal: [dim]; duration T (s) > 0; times [n] (s), clamped to [0, T].
    """
    if not (np.isfinite(duration) and duration > 0):
        raise InvalidInputError(f"duration must be > 0 s, got {duration}")
    start, goal = np.asarray(start, dtype=float), np.asarray(goal, dtype=float)
    s = np.clip(np.asarray(times, dtype=float) / duration, 0.0, 1.0)[:, None]
    delta = goal - start
    position = start + delta * (10 * s**3 - 15 * s**4 + 6 * s**5)
    velocity = delta * (30 * s**2 - 60 * s**3 + 30 * s**4) / duration
    acceleration = delta * (60 * s - 180 * s**2 + 120 * s**3) / duration**2
    return position, velocity, acceleration


def minimum_jerk_duration(start, goal, max_speed: float, min_duration: float) -> float:
    """Shortest T >= min_duration (s) whose peak speed stays within max_speed (units/s)."""
    distance = float(np.abs(np.asarray(goal, dtype=float) - np.asarray(start, dtype=float)).max())
    return max(min_duration, MIN_JERK_PEAK_SPEED * distance / max_speed)


def interpolate_poses(start, goal, count: int) -> np.ndarray:
    """``count`` poses [count, 6] from start to goal (inclusive): straight line for
    the position, geodesic (constant-axis) rotation R(s) = exp(s log(R1 R0^T)) R0."""
    start, goal = as_batch(start, 6, "start pose"), as_batch(goal, 6, "goal pose")
    s = np.linspace(0.0, 1.0, max(int(count), 2))[:, None]
    rot0, rot1 = rotation_from_rpy(start[3:]), rotation_from_rpy(goal[3:])
    phi = so3_log(rot1 @ rot0.T)
    rotations = so3_exp(s * phi) @ rot0
    positions = start[:3] + s * (goal[:3] - start[:3])
    poses = np.concatenate([positions, rpy_from_rotation(rotations)], axis=1)
    poses[-1] = goal  # exact end point
    return poses


def checked_path(robot: Robot, start, goal, max_step_m: float = 1e-3, max_step_rad: float = np.radians(1.0)):
    """A straight SE(3) path start -> goal with steps <= max_step_m / max_step_rad,
    every waypoint checked (stroke, joints, conditioning). Returns poses [n, 6];
    raises the typed error of the first infeasible waypoint."""
    start, goal = as_batch(start, 6, "start pose"), as_batch(goal, 6, "goal pose")
    # both ends first: they bound the path to the workspace (a goal 1e7 m away asked for 1e10 waypoints)
    check_pose(robot, start)
    check_pose(robot, goal)
    distance = float(np.linalg.norm(goal[:3] - start[:3]))
    angle = float(np.linalg.norm(so3_log(rotation_from_rpy(goal[3:]) @ rotation_from_rpy(start[3:]).T)))
    count = int(np.ceil(max(distance / max_step_m, angle / max_step_rad))) + 1
    poses = interpolate_poses(start, goal, count)
    check_pose(robot, poses)
    return poses
