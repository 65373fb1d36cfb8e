"""vibration.compensation and start_check's feed-forward: on a linear model of the robot (units answering h_i,
the platform the kinematic map J^-1 of them), an identification of that model makes the planned motion the
delivered one; elsewhere the vibration stays uncompensated and says why."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.analysis.fits import fit_sinusoid
from stewart_vibration.kinematics.jacobian import jacobian
from stewart_vibration.paper import paper_pose
from stewart_vibration.vibration.compensation import compensated_demands, target_motion
from stewart_vibration.vibration.decompose import decompose_vibration
from stewart_vibration.vibration.settings import default_settings, start_check
from stewart_vibration.vibration.unit_identification import VibrationIdentification

F = 35.0
UNITS = np.array([1.3, 0.8, 1.1, 0.9, 1.2, 0.75]) * np.exp(1j * np.radians([-20, 15, -5, 10, -12, 18]))


def linear_identification(robot, pose, frequencies=(30.0, 35.0, 40.0)) -> VibrationIdentification:
    platform = np.linalg.inv(jacobian(robot, pose)) @ np.diag(UNITS)
    n = len(frequencies)
    return VibrationIdentification(
        pose=np.asarray(pose, float), frequencies=np.asarray(frequencies), amplitude_m=2e-5,
        unit_response=np.tile(UNITS, (n, 1)), unit_coherence=np.ones((n, 6)), unit_uncertainty=np.zeros((n, 6)),
        platform_response=np.stack([platform] * n), platform_coherence=np.ones((n, 6, 6)),
        platform_uncertainty=np.zeros((n, 6, 6)), provenance={"date": "2026-12-05"})


@pytest.fixture
def plan(robot):
    return decompose_vibration(robot, paper_pose(robot), [0.0, 0.0, 1.0], acceleration_g=0.3, frequency=F)


def test_the_feedforward_of_a_linear_robot_delivers_the_planned_motion(robot, plan):
    ident = linear_identification(robot, plan.pose)
    demands, how = compensated_demands(ident, plan)
    assert how.startswith("identified feed-forward (35 Hz within 30-40 Hz, identified 2026-12-05")
    delivered = ident.platform_response_at(F) @ demands
    np.testing.assert_allclose(delivered, target_motion(plan), atol=1e-9 * plan.amplitude)
    np.testing.assert_allclose(demands * UNITS, plan.gains * plan.amplitude, atol=1e-9 * plan.amplitude)


def test_elsewhere_the_vibration_stays_uncompensated_and_says_why(robot, plan):
    assert compensated_demands(None, plan) == (None, "uncompensated: no identification of the vibration units "
                                                     "(identification_file)")
    moved = np.asarray(plan.pose) + [0.003, 0, 0, 0, 0, 0]
    demands, how = compensated_demands(linear_identification(robot, moved), plan)
    assert demands is None and "3.00 mm / 0.00 deg from this pose" in how
    demands, how = compensated_demands(linear_identification(robot, plan.pose, (40.0, 50.0)), plan)
    assert demands is None and "outside the identified band 40-50 Hz" in how


def test_start_check_streams_the_feedforward(robot):
    pose = paper_pose(robot)
    s = default_settings(robot)
    s.update(direction=[0.0, 0.0, 1.0], frame="platform", acceleration_g=0.3, frequency_hz=F, duration_s=2.0,
             ramp_s=0.2)
    ident = linear_identification(robot, pose)
    started = start_check(robot, pose, s, identification=ident)
    assert started.compensation.startswith("identified feed-forward")
    steady = (started.first.times > 0.3) & (started.first.times < 1.7)
    fit = fit_sinusoid(started.first.times[steady], started.first.position[steady], F)
    demands, _ = compensated_demands(ident, started.plan)
    np.testing.assert_allclose(fit.complex_amplitude, demands, atol=1e-6 * started.plan.amplitude)
    plain = start_check(robot, pose, s)
    assert plain.compensation.startswith("uncompensated")
    fit = fit_sinusoid(plain.first.times[steady], plain.first.position[steady], F)
    np.testing.assert_allclose(np.abs(fit.complex_amplitude), np.abs(plain.plan.gains) * plain.plan.amplitude,
                               rtol=1e-3)
