"""Decoded-message -> array helpers that need no rclpy (messages from the MCAP decoder)."""

from __future__ import annotations

import numpy as np

from ..kinematics.rotations import rpy_from_quaternion
from ..robot import LEG_NAMES, VIB_NAMES


def stamp_s(header) -> float:
    """A std_msgs/Header's stamp in seconds (sec + nanosec * 1e-9)."""
    return header.stamp.sec + header.stamp.nanosec * 1e-9


def pose_array(messages) -> tuple[np.ndarray, np.ndarray]:
    """PoseStamped messages -> (times [n] s, poses [n, 6])."""
    if not messages:
        return np.empty(0), np.empty((0, 6))
    times = np.array([stamp_s(m.header) for m in messages])
    pos = np.array([[m.pose.position.x, m.pose.position.y, m.pose.position.z] for m in messages])
    quat = np.array([[m.pose.orientation.x, m.pose.orientation.y, m.pose.orientation.z, m.pose.orientation.w]
                     for m in messages])
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    return times, np.concatenate([pos, rpy_from_quaternion(quat)], axis=1)


def joint_arrays(messages, names=None) -> tuple[np.ndarray, dict]:
    """JointState messages -> (times [n], {position, velocity, effort: [n, k]}) in ``names`` order
    (default leg_1..6, vib_1..6); messages missing a name are skipped."""
    names = list(names or LEG_NAMES + VIB_NAMES)
    cols: dict[str, list[list[float]]]
    times, cols = [], {"position": [], "velocity": [], "effort": []}
    for m in messages:
        index = {n: i for i, n in enumerate(m.name)}
        if any(n not in index for n in names):
            continue
        order = [index[n] for n in names]
        times.append(stamp_s(m.header))
        for key in cols:
            values = list(getattr(m, key))
            cols[key].append([values[i] for i in order] if len(values) == len(m.name) else [np.nan] * len(names))
    k = len(names)
    return np.array(times), {key: np.array(v).reshape(-1, k) for key, v in cols.items()}
