"""Planner helpers: ramped leg commands and the planned platform motion."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration import (
    decompose_vibration,
    inverse_kinematics,
    platform_vibration_motion,
    sample_leg_vibration,
)
from stewart_vibration.errors import InvalidInputError
from stewart_vibration.paper import paper_pose
from stewart_vibration.vibration import envelope
from stewart_vibration.vibration.waveform import fade_out, sinusoid


def central_difference(values, dt):
    return (values[2:] - values[:-2]) / (2 * dt)


def test_envelope_is_smooth_and_bounded():
    dt = 1e-5
    t = np.arange(-0.01, 0.31, dt)
    e, de, dde = envelope(t, duration=0.3, ramp_time=0.05)
    assert e[t < 0].max() == 0 and e[t > 0.3].max() == 0
    inside = (t > 0.05) & (t < 0.25)
    np.testing.assert_allclose(e[inside], 1.0)
    assert e.min() >= 0 and e.max() <= 1
    np.testing.assert_allclose(central_difference(e, dt), de[1:-1], atol=1e-6 * np.abs(de).max() + 1e-9)
    np.testing.assert_allclose(central_difference(de, dt), dde[1:-1], atol=1e-3 * np.abs(dde).max())
    # continuity of the derivatives at the ramp ends: no jumps bigger than one step's worth
    assert np.abs(np.diff(de)).max() < np.abs(dde).max() * dt * 1.01
    assert np.abs(np.diff(dde)).max() < 60 / 0.05**3 * dt * 1.01  # |e'''| <= 60 / T^3 for the quintic


@pytest.mark.parametrize("rotation", [False, True])
def test_leg_commands_and_platform_motion_agree(robot, rotation):
    pose = paper_pose(robot)
    kw = dict(rotation_axis=[1, 0, 0], rotation_point=[0, 0, 0.08], amplitude=4e-4) if rotation else {}
    plan = decompose_vibration(robot, pose, frequency=35.0, **kw)
    dt = 2e-5
    t = np.arange(0.0, 0.2, dt)
    legs = sample_leg_vibration(robot, plan, t, duration=0.2, ramp_time=0.05)
    motion = platform_vibration_motion(plan, t, duration=0.2, ramp_time=0.05)
    # exact commands = IK of the planned poses (independent path through inverse_kinematics)
    expected = inverse_kinematics(robot, motion.pose) - inverse_kinematics(robot, pose)
    np.testing.assert_allclose(legs.position, expected, atol=2e-15, rtol=0)
    assert np.abs(legs.position[0]).max() < 1e-15 and np.abs(legs.position[-1]).max() < 1e-12
    # analytic derivatives vs finite differences, scaled by the finite differences (not the values under
    # test). Central differences err by (w dt)^2 / 6 = 3e-6 relative on the 35 Hz sine; the third
    # derivative of the quintic ramp jumps at 0, 0.05, 0.15 and 0.2 s, so stencils there are left out.
    # The second-order terms (l'' delta'^2 of the leg accelerations, w x (w x r) delta'^2 of the platform)
    # are ~4e-4 of the peak, so a wrong one fails.
    smooth = np.ones(t.size - 2, bool)
    for knot in (0.0, 0.05, 0.15, 0.2):
        smooth &= np.abs(t[1:-1] - knot) > 2.5 * dt
    for value, rate in (
        (legs.position, legs.velocity),
        (legs.velocity, legs.acceleration),
        (motion.position, motion.velocity),
        (motion.velocity, motion.acceleration),
        (motion.angular_velocity, motion.angular_acceleration),
    ):
        fd = central_difference(value, dt)
        scale = np.abs(fd).max()
        assert np.all(np.isfinite(rate))
        if rotation or value is not motion.angular_velocity:
            assert scale > 0
        np.testing.assert_allclose(rate[1:-1][smooth], fd[smooth], rtol=0, atol=2e-5 * scale)
    # and the angular velocity is the rotation's: [w]x = R' R^T (independent of the plan's screw)
    r_dot = central_difference(motion.rotation, dt)
    w_skew = r_dot @ np.swapaxes(motion.rotation[1:-1], -1, -2)
    w_fd = np.stack([w_skew[:, 2, 1], w_skew[:, 0, 2], w_skew[:, 1, 0]], axis=-1)
    np.testing.assert_allclose(motion.angular_velocity[1:-1], w_fd, rtol=0,
                               atol=2e-5 * np.abs(w_fd).max() + 1e-12 * (not rotation))
    # steady state: peak leg acceleration ~ |k| A w^2 (linear), planned platform vibration amplitude A
    steady = (t > 0.06) & (t < 0.14)
    peak = np.abs(legs.acceleration[steady]).max(axis=0)
    big = np.abs(plan.gains) > 0.2  # small-gain legs carry a relatively larger second-order term
    first_order = np.abs(plan.gains) * plan.amplitude * (2 * np.pi * 35) ** 2
    np.testing.assert_allclose(peak[big], first_order[big], rtol=5e-3)
    np.testing.assert_allclose(peak, first_order, rtol=0.05)
    linear = sample_leg_vibration(robot, plan, t, duration=0.2, ramp_time=0.05, method="linear")
    assert np.abs(linear.position - legs.position).max() < 5e-3 * np.abs(legs.position).max()


def test_translation_motion_is_along_the_force_line(robot):
    pose = paper_pose(robot)
    plan = decompose_vibration(robot, pose, acceleration_g=0.3, frequency=35.0)
    t = np.linspace(0, 1 / 35, 200)
    motion = platform_vibration_motion(plan, t)
    dp = motion.position - pose[:3]
    np.testing.assert_allclose(dp, np.outer(plan.amplitude * np.sin(2 * np.pi * 35 * t), plan.direction), atol=1e-18)
    np.testing.assert_allclose(motion.pose[:, 3:], np.tile(pose[3:], (t.size, 1)), atol=1e-14)
    assert np.abs(motion.angular_velocity).max() == 0
    acc = np.linalg.norm(motion.acceleration, axis=1).max()
    assert acc == pytest.approx(0.3 * 9.80665, rel=1e-3)


def test_ramped_sinusoid_with_an_overlapping_fade_matches_finite_differences():
    """delta = e(t) g(t) A sin(w t + phase) with the fade-out starting inside the ramp-in, so the product
    rule's cross term 2 e' g' matters: analytic rate and acceleration against central differences
    (error (w dt)^2 / 6 ~ 1e-6 of the peak away from the ramps' knots)."""
    dt = 1e-5
    t = np.arange(-0.01, 0.12, dt)
    ramp, start = 0.05, 0.02  # ramp-in over 0..0.05 s, fade-out over 0.02..0.07 s
    fade = fade_out(t, start, ramp)
    assert np.all(fade[0][t <= start] == 1.0) and np.all(fade[0][t >= start + ramp] == 0.0)
    value, rate, accel = sinusoid(t, 1e-4, 35.0, 0.3, ramp_time=ramp, fade=fade)
    assert np.all(value[(t <= 0) | (t >= start + ramp)] == 0.0)
    smooth = np.ones(t.size - 2, bool)
    for knot in (0.0, start, ramp, start + ramp):
        smooth &= np.abs(t[1:-1] - knot) > 2.5 * dt
    for f, df in ((value, rate), (rate, accel)):
        fd = central_difference(f, dt)
        np.testing.assert_allclose(df[1:-1][smooth], fd[smooth], rtol=0, atol=1e-5 * np.abs(fd).max())


@pytest.mark.parametrize("ramp", [-0.01, np.nan, np.inf])
def test_envelope_rejects_a_bad_ramp_time(ramp):
    with pytest.raises(InvalidInputError, match="ramp_time"):
        envelope(np.linspace(0, 1, 5), duration=1.0, ramp_time=ramp)
