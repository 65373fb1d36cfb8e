"""Independent references for the vibration tests (no stewart_vibration.vibration code).

Rotation, leg vectors and the Jacobian are rebuilt here from the hinge
points in the robot's YAML file (yaml.safe_load and the hinge-circle formula
of ``reference.config_hinges``, not the library's parser), so the tests
compare against separate code.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from reference import config_hinges


@lru_cache(maxsize=4)
def _hinges(source: str):
    return config_hinges(source)


def hinges(robot):
    """(B_i, A_i) [6, 3] rebuilt from the YAML file ``robot`` was loaded from (its ``source``)."""
    return _hinges(robot.source)


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll) built from the elementary rotations."""
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def rodrigues(axis, angle: float) -> np.ndarray:
    w = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def legs(robot, position, rotation):
    """(d [6, 3], arms R a_i [6, 3], lengths [6], unit n_i [6, 3]) by a per-leg loop."""
    base, platform = hinges(robot)
    d, arms = np.zeros((6, 3)), np.zeros((6, 3))
    for i in range(6):
        arms[i] = rotation @ platform[i]
        d[i] = position + arms[i] - base[i]
    lengths = np.sqrt((d**2).sum(axis=1))
    return d, arms, lengths, d / lengths[:, None]


def jacobian_ref(robot, pose):
    _, arms, lengths, n = legs(robot, pose[:3], rpy_matrix(*pose[3:]))
    return np.hstack([n, np.cross(arms, n)]), lengths, n


def line_angle(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.arctan2(np.linalg.norm(np.cross(a, b)), abs(a @ b)))
