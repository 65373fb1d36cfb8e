"""analysis.delivered_from_poses: a platform that moves exactly as planned (a translation along the planned
direction, sampled as the pose estimate at 500 Hz) shows the planned frequency, amplitude and direction and each
leg in its planned phase; one moving 30 deg off the plan shows A cos 30 deg along it and a 30 deg direction
error; a non-finite pose says nothing."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.analysis.delivered import UNKNOWN
from stewart_vibration.analysis.delivered_from_poses import delivered_from_poses
from stewart_vibration.paper import paper_pose
from stewart_vibration.vibration.decompose import decompose_vibration

F, A, RATE, SAMPLES = 35.0, 50e-6, 500.0, 128


def poses_along(robot, direction, phase=0.0):
    """(stamps (N,) s from t0, poses (N, 6)) of the paper pose translated by A sin(2 pi F t + phase) along
    ``direction`` (base frame)."""
    t = np.arange(SAMPLES) / RATE + 3.0
    poses = np.tile(paper_pose(robot), (SAMPLES, 1))
    unit = np.asarray(direction, float) / np.linalg.norm(direction)
    poses[:, :3] += np.outer(A * np.sin(2 * np.pi * F * t + phase), unit)
    return t, poses


def test_a_platform_moving_as_planned_shows_the_plan(robot):
    # sideways: the legs vibrate with different amplitudes and opposite phases, each checked against its plan
    plan = decompose_vibration(robot, paper_pose(robot), [1.0, 0.0, 0.0], amplitude=A, frequency=F, phase=0.4,
                               frame="base")
    assert np.ptp(np.cos(plan.leg_phases)) > 1.5
    delivered = delivered_from_poses(robot, *poses_along(robot, plan.direction, phase=0.4), plan)
    assert delivered.known and delivered.frequency_hz == pytest.approx(F, abs=0.01)
    assert delivered.amplitude_m == pytest.approx(A, rel=1e-3) and delivered.direction_error_rad < 1e-3
    assert delivered.phase_spread_rad < 0.01


def test_a_platform_moving_off_the_plan_shows_by_how_much(robot):
    plan = decompose_vibration(robot, paper_pose(robot), [0.0, 0.0, 1.0], amplitude=A, frequency=F, frame="base")
    off = np.radians(30.0)
    delivered = delivered_from_poses(robot, *poses_along(robot, [np.sin(off), 0.0, np.cos(off)]), plan)
    assert delivered.amplitude_m == pytest.approx(A * np.cos(off), rel=1e-3)
    assert delivered.direction_error_rad == pytest.approx(off, abs=1e-3)


def test_a_non_finite_pose_says_nothing(robot):
    plan = decompose_vibration(robot, paper_pose(robot), [0.0, 0.0, 1.0], amplitude=A, frequency=F, frame="base")
    stamps, poses = poses_along(robot, plan.direction)
    poses[5, 3] = np.nan
    assert delivered_from_poses(robot, stamps, poses, plan) is UNKNOWN
    assert not delivered_from_poses(robot, stamps[:10], poses[:10], plan).known  # too few cycles to judge
