"""Independent reference implementations for tests (plain loops, textbook forms).

Written separately from the library on purpose: elementary rotation matrices
multiplied in the paper's order, per-leg vector arithmetic.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import yaml

CONFIG = Path(__file__).resolve().parents[1] / "stewart_vibration" / "config" / "robot.yaml"


def rot_x(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rot_z(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def reference_rotation(roll, pitch, yaw):
    """Paper eq. 3: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    return rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)


def reference_hinges(radius, angles_deg, z=0.0):
    return [np.array([radius * math.cos(math.radians(a)), radius * math.sin(math.radians(a)), z]) for a in angles_deg]


def config_hinges(path=CONFIG):
    """(base B_i, platform A_i) as [6, 3] arrays rebuilt from the YAML text, without the library's parser."""
    geometry = yaml.safe_load(Path(path).read_text())["geometry"]
    out = []
    for side in (geometry["base"], geometry["platform"]):
        angles = [float(a) for a in side["angles_deg"]]
        out.append(np.array(reference_hinges(float(side["radius_m"]), angles, float(side["z_m"]))))
    return tuple(out)


def reference_lengths(base, platform, pose):
    """Leg lengths |p + R a_i - b_i| for one pose, one leg at a time."""
    rot = reference_rotation(*pose[3:])
    p = np.asarray(pose[:3], dtype=float)
    return np.array([math.sqrt(float(np.sum((p + rot @ platform[i] - base[i]) ** 2))) for i in range(6)])


def rodrigues(phi):
    """exp([phi]x) by the matrix exponential series (independent of the library)."""
    k = np.array([[0, -phi[2], phi[1]], [phi[2], 0, -phi[0]], [-phi[1], phi[0], 0]])
    out, term = np.eye(3), np.eye(3)
    for n in range(1, 30):
        term = term @ k / n
        out = out + term
    return out
