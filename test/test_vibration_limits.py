"""Infeasible vibration requests raise typed errors naming the leg and the limit."""

from __future__ import annotations

import numpy as np
import pytest
from vibration_reference import jacobian_ref, legs, rpy_matrix

from stewart_vibration import (
    JointLimitError,
    StrokeLimitError,
    VibrationLimitError,
    decompose_vibration,
    superpose_vibration,
)
from stewart_vibration.paper import paper_pose


def test_amplitude_beyond_the_unit_names_the_leg(robot):
    pose = paper_pose(robot)
    limit = robot.vibration_unit.amplitude_max
    amp = 1.5 * limit
    with pytest.raises(VibrationLimitError) as info:
        decompose_vibration(robot, pose, amplitude=amp, frequency=10.0)
    _, _, n = jacobian_ref(robot, pose)
    k = n @ rpy_matrix(*pose[3:])[:, 2]
    assert info.value.limit_name == "amplitude_max"
    assert info.value.leg == int(np.argmax(np.abs(k))) + 1
    assert info.value.limit == limit
    assert info.value.value > limit
    # just below the limit is accepted
    decompose_vibration(robot, pose, amplitude=0.99 * limit / np.abs(k).max(), frequency=10.0)


@pytest.mark.parametrize("frequency,name", [(0.05, "frequency_min"), (200.0, "frequency_max")])
def test_frequency_outside_the_band(robot, frequency, name):
    with pytest.raises(VibrationLimitError) as info:
        decompose_vibration(robot, robot.home_pose, amplitude=1e-6, frequency=frequency)
    assert info.value.limit_name == name
    assert info.value.leg is None


def test_acceleration_beyond_the_unit(robot):
    # 50 um at 120 Hz: ~2.9 g on a leg with k ~ 1, the unit allows 1 g
    with pytest.raises(VibrationLimitError) as info:
        decompose_vibration(robot, robot.home_pose, amplitude=50e-6, frequency=120.0)
    assert info.value.limit_name == "acceleration_max"
    assert 1 <= info.value.leg <= 6
    assert info.value.value > robot.vibration_unit.acceleration_max
    # the message gives the peak and the limit in standard gravities
    g = 9.80665
    assert f"{info.value.value / g:.6g} g" in str(info.value) and f"{info.value.limit / g:.6g} g" in str(info.value)


def test_pose_near_the_stroke_limit(robot):
    # raise the platform until the longest leg is 20 um short of stroke_max (independent IK, bisection)
    lo, hi = robot.home_pose[2], robot.home_pose[2] + 0.2
    target = robot.limits.stroke_max - 20e-6
    tilt = rpy_matrix(0.05, -0.03, 0.0)  # break the symmetry so that one leg is the longest
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        length = legs(robot, np.array([0.01, 0.005, mid]), tilt)[2].max()
        lo, hi = (mid, hi) if length < target else (lo, mid)
    pose = np.array([0.01, 0.005, lo, 0.05, -0.03, 0.0])
    lengths = legs(robot, pose[:3], tilt)[2]
    assert np.sort(lengths)[-1] - np.sort(lengths)[-2] > 1e-4
    with pytest.raises(StrokeLimitError) as info:
        decompose_vibration(robot, pose, direction=[0, 0, 1], amplitude=60e-6, frequency=35.0, frame="base")
    assert info.value.leg == int(np.argmax(lengths)) + 1
    assert info.value.limit == robot.limits.stroke_max
    assert info.value.value > robot.limits.stroke_max
    # a small vibration stays inside the stroke
    decompose_vibration(robot, pose, direction=[0, 0, 1], amplitude=10e-6, frequency=35.0, frame="base")


def test_unreachable_nominal_pose(robot):
    with pytest.raises((StrokeLimitError, JointLimitError)):
        decompose_vibration(robot, [0, 0, 0.40, 0, 0, 0], amplitude=1e-6, frequency=10.0)


def test_superpose_checks_the_unit(robot):
    table = np.tile([10e-6, 35.0, 0.0], (6, 1))
    table[3, 0] = 2 * robot.vibration_unit.amplitude_max
    with pytest.raises(VibrationLimitError) as info:
        superpose_vibration(robot, robot.home_pose, table)
    assert info.value.leg == 4 and info.value.limit_name == "amplitude_max"
    table = np.tile([10e-6, 500.0, 0.0], (6, 1))
    with pytest.raises(VibrationLimitError) as info:
        superpose_vibration(robot, robot.home_pose, table)
    assert info.value.limit_name == "frequency_max"
    # within the amplitude limit, over the acceleration limit: 60 um at 110 Hz on leg 2 is 2.9 g (unit: 1 g)
    table = np.tile([1e-6, 110.0, 0.0], (6, 1))
    table[1, 0] = 60e-6
    with pytest.raises(VibrationLimitError) as info:
        superpose_vibration(robot, robot.home_pose, table)
    assert info.value.leg == 2 and info.value.limit_name == "acceleration_max"
    assert info.value.value == pytest.approx(60e-6 * (2 * np.pi * 110.0) ** 2, rel=1e-12)


def test_pose_near_the_minimum_stroke(robot):
    """Lower the platform until the shortest leg is 20 um above stroke_min (independent IK, bisection):
    a 60 um vibration along base z shortens it past the limit on its downward half."""
    lo, hi = 0.01, robot.home_pose[2]
    target = robot.limits.stroke_min + 20e-6
    tilt = rpy_matrix(0.04, 0.02, 0.0)
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        length = legs(robot, np.array([0.005, -0.004, mid]), tilt)[2].min()
        lo, hi = (lo, mid) if length > target else (mid, hi)
    pose = np.array([0.005, -0.004, hi, 0.04, 0.02, 0.0])
    lengths = legs(robot, pose[:3], tilt)[2]
    assert np.sort(lengths)[1] - np.sort(lengths)[0] > 1e-4
    assert 0 < lengths.min() - robot.limits.stroke_min < 60e-6
    with pytest.raises(StrokeLimitError) as info:
        decompose_vibration(robot, pose, direction=[0, 0, 1], amplitude=60e-6, frequency=35.0, frame="base")
    assert info.value.leg == int(np.argmin(lengths)) + 1
    assert info.value.limit == robot.limits.stroke_min and info.value.value < robot.limits.stroke_min


def test_linear_method_peak_acceleration_and_limit(robot):
    """method="linear": peak leg acceleration |k_i| A (2 pi f)^2 exactly, and the unit limit applies to it."""
    pose = paper_pose(robot)
    plan = decompose_vibration(robot, pose, amplitude=20e-6, frequency=60.0, method="linear")
    _, _, n = jacobian_ref(robot, pose)
    k = n @ rpy_matrix(*pose[3:])[:, 2]
    np.testing.assert_allclose(plan.peak_leg_acceleration, np.abs(k) * 20e-6 * (2 * np.pi * 60.0) ** 2, rtol=1e-12)
    with pytest.raises(VibrationLimitError) as info:  # 50 um at 100 Hz: |k| ~ 0.9 of 19.7 m/s^2 > 1 g
        decompose_vibration(robot, pose, amplitude=50e-6, frequency=100.0, method="linear")
    assert info.value.limit_name == "acceleration_max"
    assert info.value.leg == int(np.argmax(np.abs(k))) + 1
