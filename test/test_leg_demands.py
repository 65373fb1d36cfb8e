"""vibration.leg_demands: complex leg demands against the decomposition's own linear signals, the
feed-forward through a linear model of the robot (kinematic map times unit responses), and blended demands
against finite differences."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.errors import InvalidInputError
from stewart_vibration.kinematics.jacobian import jacobian
from stewart_vibration.paper import paper_pose
from stewart_vibration.vibration.decompose import decompose_vibration
from stewart_vibration.vibration.leg_demands import (
    blended_demand_samples,
    decomposition_demands,
    feedforward_demands,
)
from stewart_vibration.vibration.signals import sample_leg_vibration
from stewart_vibration.vibration.waveform import envelope

F = 35.0


@pytest.fixture
def plan(robot):
    return decompose_vibration(robot, paper_pose(robot), [0.0, 0.0, 1.0], acceleration_g=0.3, frequency=F,
                               phase=0.7)


def test_constant_demands_are_the_decompositions_linear_legs(robot, plan):
    t = np.arange(0, 1.0, 1e-3)
    u = decomposition_demands(plan)
    x, v, a = blended_demand_samples(t, F, u, u, 0.3, 0.1, envelope(t, 1.0, 0.2))
    linear = sample_leg_vibration(robot, plan, t, duration=1.0, ramp_time=0.2, method="linear")
    for ours, theirs in ((x, linear.position), (v, linear.velocity), (a, linear.acceleration)):
        np.testing.assert_allclose(ours, theirs, atol=1e-12 * np.abs(theirs).max())


def test_the_feedforward_through_the_identified_units_delivers_the_planned_platform_motion(robot, plan):
    """Platform motion = J^-1 diag(H) u: with u the feed-forward of H, the decomposition's twist A exp(i phase)."""
    rng = np.random.default_rng(1)
    units = (1 + rng.uniform(-0.2, 0.2, 6)) * np.exp(1j * np.radians(rng.uniform(-30, 30, 6)))
    platform = np.linalg.inv(jacobian(robot, plan.pose)) @ np.diag(units)
    delivered = platform @ feedforward_demands(decomposition_demands(plan), units)
    np.testing.assert_allclose(delivered, plan.twist * plan.amplitude * np.exp(1j * plan.phase),
                               atol=1e-9 * plan.amplitude)
    with pytest.raises(InvalidInputError, match="cannot be compensated"):
        feedforward_demands(decomposition_demands(plan), np.r_[units[:5], 0.01])


def test_a_blend_is_smooth_and_joins_the_demands_on_either_side(plan):
    dt = 1e-5
    t = np.arange(0.0, 0.6, dt)
    before = decomposition_demands(plan)
    after = before * 1.3 * np.exp(0.4j)
    x, v, a = blended_demand_samples(t, F, before, after, 0.2, 0.15, envelope(t))
    np.testing.assert_allclose(np.gradient(x, dt, axis=0)[1:-1], v[1:-1], atol=2e-5 * np.abs(v).max())
    np.testing.assert_allclose(np.gradient(v, dt, axis=0)[1:-1], a[1:-1], atol=2e-5 * np.abs(a).max())
    steady = envelope(t)
    x0, *_ = blended_demand_samples(t, F, before, before, 0.2, 0.15, steady)
    x1, *_ = blended_demand_samples(t, F, after, after, 0.2, 0.15, steady)
    assert np.array_equal(x[t <= 0.2], x0[t <= 0.2])  # a window sampled before the blend splices on exactly
    np.testing.assert_allclose(x[t >= 0.35], x1[t >= 0.35], atol=1e-18)
    with pytest.raises(InvalidInputError):
        blended_demand_samples(t, F, before, after, 0.2, 0.0, steady)
