"""Leg space -> platform motion, the vib command buffer and the wrench map (pure core)."""

from __future__ import annotations

import numpy as np
import pytest
from reference import config_hinges, reference_lengths

from stewart_vibration import decompose_vibration, inverse_kinematics, jacobian, platform_vibration_motion
from stewart_vibration.dynamics.newton_euler import leg_forces
from stewart_vibration.dynamics.platform_trajectory import SinusoidalTrajectory
from stewart_vibration.estimation import (
    RunningForceError,
    external_wrench,
    platform_accel,
    platform_twist,
)
from stewart_vibration.kinematics.legs import leg_motion
from stewart_vibration.paper import paper_pose


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


H = 1e-4  # s, step of the 4th-order central differences below


def ik_derivatives(robot, pose_at, t):
    """Hinge lengths L and 4th-order central differences L_dot, L_ddot [n, 6] of the reference IK
    (hinges rebuilt from robot.yaml, leg by leg) along the pose path pose_at(t)."""
    base, platform = config_hinges(robot.source)
    lengths = {k: np.array([reference_lengths(base, platform, q) for q in pose_at(t + k * H)]) for k in range(-2, 3)}
    rate = (lengths[-2] - 8 * lengths[-1] + 8 * lengths[1] - lengths[2]) / (12 * H)
    accel = (-lengths[-2] + 16 * lengths[-1] - 30 * lengths[0] + 16 * lengths[1] - lengths[2]) / (12 * H * H)
    return lengths[0], rate, accel


def rel_err(got, ref):
    return np.abs(got - ref).max() / np.abs(ref).max()


@pytest.mark.parametrize("kind", ["translation", "rotation"])
def test_planned_vibration_leg_rates_match_ik_finite_differences(robot, kind):
    """Planned 35 Hz vibration: leg_motion's L_dot, L_ddot and the inverse maps against finite differences
    of an independent IK along the analytic pose path (no round trip through leg_motion).

    Error budget (relative to the peak): truncation (2 pi f H)^4 / 30 ~ 1e-8, round-off
    ~ 5 eps L / (12 H^2) / L_ddot ~ 1e-8. The velocity-product part of L_ddot that
    platform_accel subtracts (|v_A,perp|^2 / l, s.(w x (w x r))) is 1e-5 .. 1e-3 of the peak,
    so a wrong or missing term there fails by orders of magnitude.
    """
    if kind == "translation":
        plan = decompose_vibration(robot, paper_pose(robot), acceleration_g=0.3, frequency=35.0)
    else:
        plan = decompose_vibration(robot, paper_pose(robot), rotation_axis=[0.3, -0.2, 1.0],
                                   rotation_point=[0.02, 0.01, 0.08], amplitude=4e-4, frequency=35.0)
    ramp = 0.1  # quintic ramp: its third derivative jumps at 0 and 0.1 s, keep the stencils off them
    t = np.r_[np.linspace(0.001, 0.099, 15), np.linspace(0.101, 0.3, 31)]

    def pose_at(tt):
        return platform_vibration_motion(plan, tt, ramp_time=ramp).pose

    length, rate, accel_l = ik_derivatives(robot, pose_at, t)
    m = platform_vibration_motion(plan, t, ramp_time=ramp)
    twist = np.hstack([m.velocity, m.angular_velocity])
    accel = np.hstack([m.acceleration, m.angular_acceleration])
    legs = leg_motion(robot, m.pose, twist, accel)
    assert rel_err(legs.length, length) < 1e-14
    assert rel_err(legs.length_rate, rate) < 1e-7
    assert rel_err(legs.length_accel, accel_l) < 1e-7
    # the inverse maps from the measured-like (finite-difference) leg rates
    got_twist = platform_twist(robot, m.pose, rate)
    assert rel_err(got_twist, twist) < 1e-6
    assert rel_err(platform_accel(robot, m.pose, twist, accel_l), accel) < 1e-6
    # the velocity-product term really matters here: without it the acceleration is visibly off
    plain = np.linalg.solve(jacobian(robot, m.pose), accel_l[..., None])[..., 0]
    assert rel_err(plain, accel) > 1e-5


def test_external_wrench_inverts_leg_forces(robot):
    motion = random_motion(robot, 5)
    s = motion.sample(np.linspace(0, 0.2, 5))
    wrench = np.array([3.0, -2.0, 15.0, 0.2, -0.1, 0.05])
    with_wrench = leg_forces(robot, s.pose, s.twist, s.accel, external_wrench=wrench)
    model = leg_forces(robot, s.pose, s.twist, s.accel)
    np.testing.assert_allclose(external_wrench(robot, s.pose, with_wrench, model), np.tile(wrench, (5, 1)),
                               atol=1e-9)


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
