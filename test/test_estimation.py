"""Leg space -> platform motion, the vib command buffer and the wrench map (pure core, issue 5)."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration import decompose_vibration, inverse_kinematics, platform_vibration_motion
from stewart_vibration.dynamics import leg_forces
from stewart_vibration.errors import InvalidInputError
from stewart_vibration.estimation import (
    RunningForceError,
    VibrationCommandBuffer,
    external_wrench,
    platform_accel,
    platform_twist,
)
from stewart_vibration.paper import paper_pose
from stewart_vibration.trajectory import SinusoidalTrajectory


def random_motion(robot, seed=3):
    rng = np.random.default_rng(seed)
    return SinusoidalTrajectory(
        paper_pose(robot), rng.uniform(-1, 1, (2, 6)) * [2e-3, 2e-3, 2e-3, 0.02, 0.02, 0.02],
        np.array([7.0, 19.0]), rng.uniform(0, 2 * np.pi, (2, 6)),
    )


def test_twist_and_accel_from_leg_rates_match_finite_differences(robot):
    motion = random_motion(robot)
    t = np.linspace(0.0, 0.5, 11)
    h = 1e-4
    lengths = [inverse_kinematics(robot, motion.sample(t + k * h).pose) for k in (-1, 0, 1)]
    rate = (lengths[2] - lengths[0]) / (2 * h)
    accel_l = (lengths[2] - 2 * lengths[1] + lengths[0]) / h**2
    truth = motion.sample(t)
    twist = platform_twist(robot, truth.pose, rate)
    accel = platform_accel(robot, truth.pose, twist, accel_l)
    np.testing.assert_allclose(twist, truth.twist, atol=5e-6 * np.abs(truth.twist).max())  # O((w h)^2)
    np.testing.assert_allclose(accel, truth.accel, atol=1e-5 * np.abs(truth.accel).max())


def test_analytic_vibration_roundtrip(robot):
    """Planned platform vibration -> leg L_dot, L_ddot (analytic) -> back to the same twist and accel."""
    from stewart_vibration.leg_kinematics import leg_motion

    plan = decompose_vibration(robot, paper_pose(robot), acceleration_g=0.3, frequency=35.0)
    t = np.linspace(0.0, 0.3, 200)
    m = platform_vibration_motion(plan, t, ramp_time=0.1)
    twist = np.hstack([m.velocity, m.angular_velocity])
    accel = np.hstack([m.acceleration, m.angular_acceleration])
    legs = leg_motion(robot, m.pose, twist, accel)
    got_twist = platform_twist(robot, m.pose, legs.length_rate)
    got_accel = platform_accel(robot, m.pose, got_twist, legs.length_accel)
    np.testing.assert_allclose(got_twist, twist, atol=1e-12)
    np.testing.assert_allclose(got_accel, accel, atol=1e-9)


def test_external_wrench_inverts_leg_forces(robot):
    motion = random_motion(robot, 5)
    s = motion.sample(np.linspace(0, 0.2, 5))
    wrench = np.array([3.0, -2.0, 15.0, 0.2, -0.1, 0.05])
    with_wrench = leg_forces(robot, s.pose, s.twist, s.accel, external_wrench=wrench)
    model = leg_forces(robot, s.pose, s.twist, s.accel)
    np.testing.assert_allclose(external_wrench(robot, s.pose, with_wrench, model), np.tile(wrench, (5, 1)),
                               atol=1e-9)


def test_vibration_buffer_interpolates_and_replaces():
    f = 35.0
    w = 2 * np.pi * f
    dt = 1e-3
    gains = np.linspace(-1, 1, 6) * 1e-5
    times = np.arange(0, 0.6, dt) + 100.0
    buf = VibrationCommandBuffer()
    buf.add(times, np.sin(w * times)[:, None] * gains, (w * np.cos(w * times))[:, None] * gains)
    probe = np.linspace(100.1, 100.5, 97)
    pos, vel, acc = buf.sample(probe)
    np.testing.assert_allclose(pos, np.sin(w * probe)[:, None] * gains, atol=1e-4 * 1e-5)
    # cubic Hermite acceleration error ~ (w dt)^2 / 12 relative (what the emulator follows)
    np.testing.assert_allclose(acc, (-w * w * np.sin(w * probe))[:, None] * gains, atol=0.01 * w * w * 1e-5)
    # a new window replaces from its first point on: zeros after 100.3
    later = times[times >= 100.3]
    buf.add(later, np.zeros((later.size, 6)), np.zeros((later.size, 6)))
    pos, _, acc = buf.sample(np.array([100.2, 100.4, 101.0, 99.0]))
    assert np.abs(pos[0]).max() > 0 and np.abs(pos[1:]).max() == 0 and np.abs(acc[1:]).max() == 0
    with pytest.raises(InvalidInputError):
        buf.add(np.array([1.0, 1.0]), np.zeros((2, 6)), np.zeros((2, 6)))
    with pytest.raises(InvalidInputError):
        buf.add(np.array([1.0, 2.0]), np.full((2, 6), np.nan), np.zeros((2, 6)))


def test_running_force_error():
    err = RunningForceError(window_s=1.0)
    t = np.arange(0, 2, 0.002)
    for ti in t:
        measured = 10 + 5 * np.sin(2 * np.pi * 35 * ti) * np.ones(6)
        err.add(ti, measured, measured - 0.05)
    s = err.summary()
    assert s["samples"] == 501
    np.testing.assert_allclose(s["rms_error_all_n"], 0.05)
    np.testing.assert_allclose(s["force_amplitude_n"], 5.0, rtol=1e-3)
    np.testing.assert_allclose(s["relative_error"], 0.01, rtol=1e-3)
