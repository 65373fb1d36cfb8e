"""Calibration poses chosen for identifiability (pure numpy): a D-optimal subset of random poses inside
the workspace and every limit, visited in a short order."""

from __future__ import annotations

import numpy as np

from ..errors import UnreachablePoseError
from ..kinematics import check_pose
from ..kinematics.rotations import rotation_from_rpy
from ..robot import Robot
from .geometry_parameters import parameters_of
from .measurement_model import TrackerNoise, parameter_jacobian, whitening

CANDIDATES = 2000


def reachable_candidates(robot: Robot, count: int, reach_m: float, tilt_rad: float,
                         rng: np.random.Generator) -> np.ndarray:
    """Up to ``count`` random poses (N, 6) about home, within +-reach_m and +-tilt_rad per axis, that pass
    every pose check of the robot (strokes, joints, conditioning)."""
    offsets = rng.uniform(-1.0, 1.0, (count, 6)) * np.array([reach_m] * 3 + [tilt_rad] * 3)
    poses = robot.home_pose + offsets
    keep = np.zeros(count, bool)
    for i, pose in enumerate(poses):  # a few thousand checks once per plan, not a hot path
        try:
            check_pose(robot, pose)
            keep[i] = True
        except UnreachablePoseError:
            pass
    return poses[keep]


def d_optimal_subset(robot: Robot, candidates: np.ndarray, count: int, frames: int,
                     noise: TrackerNoise) -> np.ndarray:
    """Indices of ``count`` candidates chosen greedily to maximise det(J^T J) of the whitened Jacobian (at
    the drawing): each step adds the pose that adds the most information to those chosen."""
    theta = parameters_of(robot)
    rotations = rotation_from_rpy(candidates[:, 3:])
    weights = whitening(theta, candidates[:, :3], rotations, np.full(len(candidates), float(frames)), noise)
    rows = np.einsum("kij,kjp->kip", weights, parameter_jacobian(theta, candidates[:, :3], rotations))
    rows_t = rows.transpose(0, 2, 1)
    information = np.eye(rows.shape[2]) * 1e-6 * np.einsum("kip,kip->", rows, rows) / rows.size
    chosen: list[int] = []
    free = np.ones(len(candidates), bool)
    for _ in range(min(count, len(candidates))):
        inverse = np.linalg.inv(information)
        gain = np.linalg.slogdet(np.eye(6) + (rows @ inverse) @ rows_t)[1]
        gain[~free] = -np.inf
        best = int(np.argmax(gain))
        chosen.append(best)
        free[best] = False
        information = information + rows[best].T @ rows[best]
    return np.array(chosen)


def short_tour(poses: np.ndarray, start: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """An order of ``poses`` (N, 6) starting nearest ``start`` (nearest neighbour, distances per ``scale``)."""
    left = list(range(len(poses)))
    order, here = [], np.asarray(start, float)
    while left:
        dist = np.abs((poses[left] - here) / scale).max(axis=1)
        nxt = left.pop(int(np.argmin(dist)))
        order.append(nxt)
        here = poses[nxt]
    return np.array(order, int)


def plan_calibration_poses(robot: Robot, count: int, frames: int, noise: TrackerNoise, seed: int = 0,
                           reach_m: float = 0.02, tilt_rad: float = np.radians(15.0)) -> np.ndarray:
    """``count`` calibration poses (count, 6) (m, rad) inside every limit, D-optimal for the 42 parameters
    with ``frames`` tracker frames averaged per pose, in a short visiting order from home.

    The defaults span the reduction workspace (+-20 mm, +-15 deg): calibrated where the robot works. A wider
    span determines each parameter better (the hinges' heights and the struts' zero offsets are told apart
    only by how much the legs turn), but the pose error inside the workspace hardly changes."""
    candidates = reachable_candidates(robot, CANDIDATES, reach_m, tilt_rad, np.random.default_rng(seed))
    chosen = candidates[d_optimal_subset(robot, candidates, count, frames, noise)]
    scale = np.array([reach_m] * 3 + [tilt_rad] * 3)
    return chosen[short_tour(chosen, robot.home_pose, scale)]
