"""Leg kinematics and analytic trajectories against finite differences."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.dynamics.platform_trajectory import (
    SinusoidalTrajectory,
    twist_from_euler_rates,
    vibration_trajectory,
)
from stewart_vibration.kinematics import inverse_kinematics, leg_vectors
from stewart_vibration.kinematics.legs import leg_motion
from stewart_vibration.kinematics.rotations import rotation_from_rpy
from stewart_vibration.paper import paper_pose

H = 1e-3  # s, step of the 4th-order central differences


def d1(f, t):
    return (-f(t + 2 * H) + 8 * f(t + H) - 8 * f(t - H) + f(t - 2 * H)) / (12 * H)


def d2(f, t):
    return (-f(t + 2 * H) + 16 * f(t + H) - 30 * f(t) + 16 * f(t - H) - f(t - 2 * H)) / (12 * H * H)


def random_trajectory(robot, seed, k=3):
    rng = np.random.default_rng(seed)
    amp = rng.uniform(-1, 1, (k, 6)) * np.array([0.004, 0.004, 0.004, 0.04, 0.04, 0.04])
    return SinusoidalTrajectory(paper_pose(robot), amp, rng.uniform(1.0, 12.0, k), rng.uniform(0, 2 * np.pi, (k, 6)))


def rel(err, ref):
    return np.abs(err).max() / np.abs(ref).max()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_leg_rates_match_finite_differences(robot, seed):
    traj = random_trajectory(robot, seed)
    t = np.linspace(0.1, 1.0, 7)

    def lengths(tt):
        return inverse_kinematics(robot, traj.pose_derivatives(tt)[0], check_limits=False)

    def axes(tt):
        d = leg_vectors(robot, traj.pose_derivatives(tt)[0])
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    samp = traj.sample(t)
    m = leg_motion(robot, samp.pose, samp.twist, samp.accel)
    assert rel(m.length - lengths(t), m.length) < 1e-14
    assert rel(m.length_rate - d1(lengths, t), m.length_rate) < 1e-6
    assert rel(m.length_accel - d2(lengths, t), m.length_accel) < 1e-6
    s_dot = d1(axes, t)
    assert rel(m.axis_rate - s_dot, m.axis_rate) < 1e-6
    assert rel(m.omega - np.cross(m.axis, s_dot), m.omega) < 1e-6
    assert rel(m.axis_accel - d2(axes, t), m.axis_accel) < 1e-6

    def omega(tt):
        s = traj.sample(tt)
        return leg_motion(robot, s.pose, s.twist, s.accel).omega

    assert rel(m.alpha - d1(omega, t), m.alpha) < 1e-6
    # the leg angular motion is normal to the leg (no spin)
    assert np.abs(np.einsum("...i,...i->...", m.omega, m.axis)).max() < 1e-12
    assert np.abs(np.einsum("...i,...i->...", m.alpha, m.axis)).max() < 1e-10


@pytest.mark.parametrize("seed", [3, 4])
def test_twist_from_euler_rates_matches_rotation_derivative(robot, seed):
    traj = random_trajectory(robot, seed)
    t = np.linspace(0.0, 0.8, 5)
    samp = traj.sample(t)

    def rot(tt):
        return rotation_from_rpy(traj.pose_derivatives(tt)[0][..., 3:])

    r_dot = d1(rot, t)
    w_skew = r_dot @ np.swapaxes(rot(t), -1, -2)  # [w]x = R' R^T
    w = np.stack([w_skew[:, 2, 1], w_skew[:, 0, 2], w_skew[:, 1, 0]], axis=-1)
    assert rel(samp.twist[:, 3:] - w, samp.twist[:, 3:]) < 1e-6

    def w_of(tt):
        return traj.sample(tt).twist[:, 3:]

    def p_of(tt):
        return traj.pose_derivatives(tt)[0][:, :3]

    assert rel(samp.accel[:, 3:] - d1(w_of, t), samp.accel[:, 3:]) < 1e-6
    assert rel(samp.twist[:, :3] - d1(p_of, t), samp.twist[:, :3]) < 1e-6
    assert rel(samp.accel[:, :3] - d2(p_of, t), samp.accel[:, :3]) < 1e-6


def test_vibration_trajectory_is_a_line_along_the_direction(robot):
    pose = paper_pose(robot)
    u = np.array([0.2, -0.3, 0.9])
    traj = vibration_trajectory(pose, u, 1e-5, 35.0, 0.4)
    s = traj.sample(np.linspace(0, 1 / 35, 2001))
    un = u / np.linalg.norm(u)
    disp = s.pose[:, :3] - pose[:3]
    assert np.abs(np.cross(disp, un)).max() < 1e-15  # roundoff of pose (0.2 m) + 10 um
    assert np.allclose(s.pose[:, 3:], pose[3:]) and not s.twist[:, 3:].any()
    assert np.allclose(s.accel[:, :3], -(2 * np.pi * 35) ** 2 * disp, rtol=0, atol=1e-9)
    assert np.abs(disp @ un).max() == pytest.approx(1e-5, rel=1e-2)
    from stewart_vibration.errors import InvalidInputError

    with pytest.raises(InvalidInputError, match="non-zero"):  # was NaN amplitudes, silently
        vibration_trajectory(pose, [0.0, 0.0, 0.0], 1e-5, 35.0)


def test_euler_rate_conversion_rejects_bad_shapes():
    from stewart_vibration.errors import InvalidInputError

    with pytest.raises(InvalidInputError):
        twist_from_euler_rates(np.zeros(5), np.zeros(6), np.zeros(6))
