"""Straight SE(3) paths of the platform, every waypoint checked (what kinematics/plan_path answers).

Under a soft-tissue load (``stewart_vibration.dynamics.tissue``) a path is also checked for the strut forces it
needs: ``check_path_forces`` predicts them quasi-statically (Newton-Euler at rest + the tissue's elastic
wrench at each waypoint) and refuses the path if any strut would exceed strut_force_max_n.
"""

from __future__ import annotations

import numpy as np

from ..dynamics.newton_euler import leg_forces
from ..dynamics.tissue import TissueModel, tissue_wrench
from ..errors import TissueLimitError
from ..input_checks import as_batch
from ..kinematics import check_pose
from ..kinematics.rotations import rotation_from_rpy, rpy_from_rotation, so3_exp, so3_log
from ..robot import Robot


def interpolate_poses(start, goal, count: int) -> np.ndarray:
    """``count`` poses [count, 6] from start to goal (inclusive): straight line for
    the position, geodesic (constant-axis) rotation R(s) = exp(s log(R1 R0^T)) R0.

    Args:
        start: start pose (6,) (m, rad).
        goal: goal pose (6,) (m, rad); the last waypoint is exactly ``goal``.
        count: number of waypoints (at least 2 are returned).

    Returns:
        Poses [max(count, 2), 6] (m, rad), evenly spaced in s from 0 to 1.

    Raises:
        InvalidInputError: ``start`` or ``goal`` is not numeric, not [..., 6] or not finite (``as_batch``).
    """
    start, goal = as_batch(start, 6, "start pose"), as_batch(goal, 6, "goal pose")
    s = np.linspace(0.0, 1.0, max(int(count), 2))[:, None]
    rot0, rot1 = rotation_from_rpy(start[3:]), rotation_from_rpy(goal[3:])
    phi = so3_log(rot1 @ rot0.T)
    rotations = so3_exp(s * phi) @ rot0
    positions = start[:3] + s * (goal[:3] - start[:3])
    poses = np.concatenate([positions, rpy_from_rotation(rotations)], axis=1)
    poses[-1] = goal  # exact end point
    return poses


def predicted_leg_forces(robot: Robot, poses, tissue: TissueModel | None = None) -> np.ndarray:
    """Quasi-static axial strut forces [..., 6] (N) at poses [..., 6]: Newton-Euler at rest (gravity) plus
    the tissue's elastic wrench (no damping: moves are slow; their inertial forces are ~0.1 N).

    Args:
        robot: the robot.
        poses: platform poses [..., 6] (m, rad).
        tissue: optional soft-tissue load; None = gravity only.

    Returns:
        Axial forces [..., 6] (N, positive extends the strut).

    Raises:
        InvalidInputError: a pose is not [..., 6] or not finite (``tissue_wrench`` / ``leg_forces``).
        ValueError: ``poses`` is not numeric (numpy's conversion).
    """
    poses = np.asarray(poses, dtype=float)
    zero = np.zeros_like(poses)
    wrench = None if tissue is None else tissue_wrench(tissue, poses)
    return leg_forces(robot, poses, zero, zero, external_wrench=wrench)


def check_path_forces(robot: Robot, poses, tissue: TissueModel | None = None, first_index: int = 0,
                      count: int | None = None) -> np.ndarray:
    """Predicted strut forces [n, 6] along waypoints [n, 6] (``predicted_leg_forces``), refused over
    strut_force_max_n.

    Args:
        robot: the robot (limits.strut_force_max, N).
        poses: waypoints [..., 6] (m, rad), flattened to [n, 6].
        tissue: optional soft-tissue load.
        first_index: index of ``poses[0]`` in the whole path, for the message.
        count: number of waypoints of the whole path, for the message; None = n + ``first_index``.

    Returns:
        Axial forces [n, 6] (N).

    Raises:
        InvalidInputError: a pose is not numeric, not [..., 6] or not finite (``as_batch``).
        TissueLimitError: |force| > strut_force_max on some waypoint: names the first such waypoint (index +
            ``first_index`` of ``count``, and its pose) and its leg with the largest |force| / limit; ``leg``
            (1..6), ``limit_name`` "strut_force_max", ``value`` (N), ``limit`` (N), ``waypoint`` (index).
    """
    poses = as_batch(poses, 6, "poses").reshape(-1, 6)
    forces = predicted_leg_forces(robot, poses, tissue)
    limit = robot.limits.strut_force_max
    over = np.abs(forces) > limit
    if over.any():
        k = int(np.argmax(over.any(axis=1)))
        leg = int(np.argmax(np.abs(forces[k]) / limit))
        load = f" under the tissue load '{tissue.name}'" if tissue is not None else ""
        pose = ", ".join(f"{v:.4f}" for v in poses[k])
        total = len(poses) + first_index if count is None else count
        raise TissueLimitError(
            f"leg_{leg + 1}: predicted force {forces[k, leg]:.1f} N at waypoint {k + first_index} of {total} "
            f"(pose [{pose}]) "
            f"exceeds strut_force_max_n {limit:g} N{load}", leg=leg + 1, limit_name="strut_force_max",
            value=float(forces[k, leg]), limit=limit, waypoint=k + first_index)
    return forces


def checked_path(robot: Robot, start, goal, max_step_m: float = 1e-3, max_step_rad: float = np.radians(1.0),
                 tissue: TissueModel | None = None):
    """A straight SE(3) path start -> goal with steps <= max_step_m / max_step_rad, every waypoint checked.

    The checks are stroke, joints and conditioning; with ``tissue`` also the predicted strut forces
    (``check_path_forces``) from the first waypoint after the start: the robot is at the start already, and a
    path away from an overload must stay possible. Both ends are checked first, so they bound the path to the
    workspace.

    Args:
        robot: the robot.
        start: start pose (6,) (m, rad).
        goal: goal pose (6,) (m, rad).
        max_step_m: largest position step between waypoints (m).
        max_step_rad: largest rotation step between waypoints (rad).
        tissue: optional soft-tissue load whose predicted strut forces are checked too.

    Returns:
        Poses [n, 6] (m, rad), poses[0] = start, poses[-1] = goal (waypoint k = poses[k]).

    Raises:
        InvalidInputError: ``start`` or ``goal`` is not numeric, not [..., 6] or not finite.
        UnreachablePoseError, StrokeLimitError, JointLimitError, SingularPoseError: the first infeasible
            waypoint (``check_pose``; start and goal before the waypoints between).
        TissueLimitError: with ``tissue``, a strut's predicted force exceeds strut_force_max
            (``check_path_forces``).
    """
    start, goal = as_batch(start, 6, "start pose"), as_batch(goal, 6, "goal pose")
    # both ends first: they bound the path to the workspace (a goal 1e7 m away asked for 1e10 waypoints)
    check_pose(robot, start)
    check_pose(robot, goal)
    distance = float(np.linalg.norm(goal[:3] - start[:3]))
    angle = float(np.linalg.norm(so3_log(rotation_from_rpy(goal[3:]) @ rotation_from_rpy(start[3:]).T)))
    count = int(np.ceil(max(distance / max_step_m, angle / max_step_rad))) + 1
    poses = interpolate_poses(start, goal, count)
    check_pose(robot, poses)
    if tissue is not None:
        check_path_forces(robot, poses[1:], tissue, first_index=1, count=len(poses))
    return poses
