"""Straight SE(3) paths of the platform, every waypoint checked (what kinematics/plan_path answers).

Under a soft-tissue load (``stewart_vibration.dynamics.tissue``) a path is also checked for the strut forces it
needs: ``check_path_forces`` predicts them quasi-statically (Newton-Euler at rest + the tissue's elastic
wrench at each waypoint) and refuses the path if any strut would exceed strut_force_max_n.
"""

from __future__ import annotations

import numpy as np

from ..dynamics.newton_euler import leg_forces
from ..dynamics.tissue import TissueModel, tissue_wrench
from ..errors import ActuatorLimitError
from ..input_checks import as_batch
from ..kinematics import check_pose
from ..kinematics.rotations import rotation_from_rpy, rpy_from_rotation, so3_exp, so3_log
from ..robot import Robot


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


def predicted_leg_forces(robot: Robot, poses, tissue: TissueModel | None = None) -> np.ndarray:
    """Quasi-static axial strut forces [..., 6] (N) at poses [..., 6]: Newton-Euler at rest (gravity) plus
    the tissue's elastic wrench (no damping: moves are slow; their inertial forces are ~0.1 N)."""
    poses = np.asarray(poses, dtype=float)
    zero = np.zeros_like(poses)
    wrench = None if tissue is None else tissue_wrench(tissue, poses)
    return leg_forces(robot, poses, zero, zero, external_wrench=wrench)


def check_path_forces(robot: Robot, poses, tissue: TissueModel | None = None, first_index: int = 0,
                      count: int | None = None) -> np.ndarray:
    """Predicted strut forces [n, 6] along waypoints [n, 6] (``predicted_leg_forces``); raises
    ActuatorLimitError naming the leg and the waypoint (index + ``first_index`` of ``count``, and its pose)
    of the first one on which a strut would exceed strut_force_max_n."""
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
        raise ActuatorLimitError(
            f"leg_{leg + 1}: predicted force {forces[k, leg]:.1f} N at waypoint {k + first_index} of {total} "
            f"(pose [{pose}]) "
            f"exceeds strut_force_max_n {limit:g} N{load}", leg=leg + 1, limit_name="strut_force_max",
            value=float(forces[k, leg]), limit=limit)
    return forces


def checked_path(robot: Robot, start, goal, max_step_m: float = 1e-3, max_step_rad: float = np.radians(1.0),
                 tissue: TissueModel | None = None):
    """A straight SE(3) path start -> goal with steps <= max_step_m / max_step_rad,
    every waypoint checked (stroke, joints, conditioning; with ``tissue`` also the predicted strut forces,
    ``check_path_forces``, from the first waypoint after the start: the robot is at the start already, and a
    path away from an overload must stay possible). Returns poses [n, 6]; raises the typed error of the first
    infeasible waypoint (waypoint k = poses[k])."""
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
