"""Minimum-jerk profiles and checked SE(3) paths."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration import StrokeLimitError
from stewart_vibration.kinematics.rotations import rotation_from_rpy
from stewart_vibration.motion.paths import checked_path, interpolate_poses
from stewart_vibration.motion.profiles import MIN_JERK_PEAK_SPEED, minimum_jerk, minimum_jerk_duration


def test_minimum_jerk_boundary_conditions_and_derivatives():
    start, goal, duration = np.array([0.17, 0.18]), np.array([0.19, 0.16]), 2.0
    times = np.linspace(0, duration, 2001)
    pos, vel, acc = minimum_jerk(start, goal, duration, times)
    assert np.allclose(pos[0], start) and np.allclose(pos[-1], goal)
    assert np.allclose(vel[[0, -1]], 0) and np.allclose(acc[[0, -1]], 0)
    dt = times[1] - times[0]
    assert np.allclose(np.gradient(pos, dt, axis=0)[1:-1], vel[1:-1], atol=1e-6)
    assert np.allclose(np.gradient(vel, dt, axis=0)[1:-1], acc[1:-1], atol=1e-5)
    peak = np.abs(vel).max(axis=0)
    assert np.allclose(peak, MIN_JERK_PEAK_SPEED * np.abs(goal - start) / duration, rtol=1e-6)


def test_duration_respects_speed_limit():
    duration = minimum_jerk_duration([0.17] * 6, [0.21] + [0.17] * 5, max_speed=0.02, min_duration=0.5)
    _, vel, _ = minimum_jerk(np.full(6, 0.17), np.array([0.21] + [0.17] * 5), duration, np.linspace(0, duration, 999))
    assert np.abs(vel).max() <= 0.02 + 1e-12
    assert minimum_jerk_duration([0.17], [0.17], 0.02, 0.5) == 0.5


def test_interpolated_rotation_has_constant_axis():
    start = np.array([0, 0, 0.16, 0, 0, 0])
    goal = np.array([0.01, 0, 0.17, 0.2, -0.1, 0.3])
    poses = interpolate_poses(start, goal, 11)
    assert np.allclose(poses[0], start) and np.allclose(poses[-1], goal)
    rots = rotation_from_rpy(poses[:, 3:])
    steps = [rots[i + 1] @ rots[i].T for i in range(10)]
    assert all(np.allclose(steps[0], s, atol=1e-12) for s in steps)  # equal geodesic steps


def test_checked_path(robot):
    goal = robot.home_pose + np.array([0.01, 0.0, 0.005, 0.1, 0.0, 0.0])
    path = checked_path(robot, robot.home_pose, goal)
    assert len(path) >= 0.1 / np.radians(1.0)
    unreachable = robot.home_pose + np.array([0.0, 0.0, 0.2, 0, 0, 0])
    with pytest.raises(StrokeLimitError):
        checked_path(robot, robot.home_pose, unreachable)
