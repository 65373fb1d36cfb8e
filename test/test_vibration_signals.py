"""Planner helpers: ramped leg commands and the planned platform motion (issue 3)."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration import (
    decompose_vibration,
    inverse_kinematics,
    platform_vibration_motion,
    sample_leg_vibration,
)
from stewart_vibration.paper import paper_pose
from stewart_vibration.vibration import envelope


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
    # analytic derivatives vs finite differences
    for value, rate, scale in (
        (legs.position, legs.velocity, np.abs(legs.velocity).max()),
        (legs.velocity, legs.acceleration, np.abs(legs.acceleration).max()),
        (motion.position, motion.velocity, np.abs(motion.velocity).max()),
        (motion.velocity, motion.acceleration, np.abs(motion.acceleration).max()),
        (motion.angular_velocity, motion.angular_acceleration, np.abs(motion.angular_acceleration).max() + 1e-30),
    ):
        np.testing.assert_allclose(central_difference(value, dt), rate[1:-1], atol=2e-3 * scale)
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
