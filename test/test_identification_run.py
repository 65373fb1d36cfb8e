"""vibration.identification_run on the in-process emulator (MuJoCo, no ROS): on the ideal plant each unit
answers its demand exactly and the platform moves by the kinematic map J^-1 (the robot's drawing); on the
realistic plant the identification from the robot's own sensors (unit sensors, IMU) matches what the plant's
truth shows (the units' true displacements, the platform's true pose), which the controller never sees."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from emulator_runs import move_and_settle

from stewart_vibration.emulation.control_bench import run_excitation
from stewart_vibration.emulation.emulator import HardwareEmulator
from stewart_vibration.emulation.plant import load_plant
from stewart_vibration.errors import InvalidInputError
from stewart_vibration.kinematics.jacobian import jacobian
from stewart_vibration.paper import paper_pose
from stewart_vibration.sim.mjcf import load_simulation_settings
from stewart_vibration.vibration.frequency_response import sine_response
from stewart_vibration.vibration.identification_run import excitation_plan, identify_units
from stewart_vibration.vibration.unit_identification import quality_problems

pytestmark = pytest.mark.slow

CONFIG = Path(__file__).resolve().parents[1] / "stewart_vibration" / "config"
AMPLITUDE = 20e-6  # m: a fifth of the units' travel, well inside every limit
FREQUENCIES = (30.0, 35.0, 40.0)


def identified(robot, plant=None):
    emu = HardwareEmulator(robot, load_simulation_settings(timestep=1 / 2000), plant=plant)
    pose = paper_pose(robot)
    move_and_settle(emu, robot, pose)
    steps = excitation_plan(FREQUENCIES, min_measure_s=0.6)
    rec = run_excitation(emu, steps, AMPLITUDE, truth=True)
    # the device facts a controller has from the data sheets: the IMU reports the mean specific force over its
    # 2 ms sample period (integrate and dump); a unit's sensor reports the reading its 2 kHz firmware used last
    ident = identify_units(steps, AMPLITUDE, pose, rec["times"], rec["units"], rec["accel"], rec["gyro"],
                           gravity=robot.gravity, accel_average_s=0.002,
                           unit_sensor_latency_s=0.0005 if plant is not None else 0.0,
                           provenance={"test": "in-process emulator"})
    return ident, steps, rec, pose


def truth_responses(steps, rec, pose):
    """The same responses from the plant's truth: true unit displacements and the true platform pose."""
    from stewart_vibration.vibration.identification_run import step_samples

    units, platform = {}, {}
    t, true_pose = rec["times"], rec["true_pose"]
    for step in steps:
        first, last = step.measured
        inside = (t >= first - 1e-9) & (t <= last + 1e-9)
        demand = step_samples(step, AMPLITUDE, t[inside])[0][:, step.unit]
        motion = true_pose[inside] - true_pose[inside].mean(axis=0)  # small angles: rpy rates ~ rotation vector
        r = sine_response(t[inside], demand, np.column_stack([rec["true_units"][inside], motion]), step.frequency)
        units[step.frequency, step.unit] = r.response[step.unit]
        platform[step.frequency, step.unit] = r.response[6:9]  # translation only (rpy is not the base-frame
    return units, platform                                      # rotation vector away from zero roll/pitch)


def test_on_the_ideal_plant_the_units_are_the_identity_and_the_platform_the_kinematic_map(robot):
    """The platform follows the kinematic map with the emulated drives' own transport delay (under one
    0.5 ms physics step): the same pure delay in every entry at every frequency."""
    ident, *_ = identified(robot)
    np.testing.assert_allclose(ident.unit_response, 1.0, atol=1e-3)
    kinematic = np.linalg.inv(jacobian(robot, paper_pose(robot)))
    delays = []
    row_size = np.abs(kinematic).max(axis=1, keepdims=True)  # per DOF (m/m or rad/m)
    for k, f in enumerate(FREQUENCIES):
        ratio = ident.platform_response[k] / kinematic
        big = np.abs(kinematic) > 0.2 * row_size
        lag = float(np.median(-np.angle(ratio[big]) / (2 * np.pi * f)))  # s
        residual = np.abs(ident.platform_response[k] - kinematic * np.exp(-2j * np.pi * f * lag))
        assert (residual < 0.01 * row_size).all(), (f, lag, (residual / row_size).max())
        delays.append(lag)
    assert 0 <= min(delays) and max(delays) < 0.0005 and np.ptp(delays) < 2e-5, delays
    assert quality_problems(ident) == []


def test_on_the_realistic_plant_the_identification_matches_the_plants_truth(robot):
    plant = load_plant(CONFIG / "plant_realistic.yaml", robot, seed=3)
    ident, steps, rec, pose = identified(robot, plant)
    assert quality_problems(ident) == [], quality_problems(ident)
    units, platform = truth_responses(steps, rec, pose)
    for (f, j), truth in units.items():
        found = ident.unit_response[FREQUENCIES.index(f), j]
        assert abs(abs(found) / abs(truth) - 1) < 0.02, (f, j, found, truth)
        assert abs(np.degrees(np.angle(found / truth))) < 1.0, (f, j, found, truth)
    # the IMU's samples (MuJoCo's velocities, staggered half a 0.5 ms step behind the positions) lag the true
    # pose by a common delay under one physics step: the same in every direction, so the motion's direction and
    # size are the truth's (what the vibration control needs)
    for (f, j), truth in platform.items():
        found = ident.platform_response[FREQUENCIES.index(f), :3, j]
        lag = -np.angle(np.vdot(truth, found)) / (2 * np.pi * f)
        assert 0 <= lag < 0.0005, (f, j, lag)
        aligned = found * np.exp(2j * np.pi * f * lag)
        assert np.linalg.norm(aligned - truth) < 0.02 * np.linalg.norm(truth), (f, j, found, truth)
    # the units are not ideal here: resonant, spread; the identification sees it
    assert np.abs(np.abs(ident.unit_response) - 1).max() > 0.1


def test_a_record_that_misses_a_step_is_refused(robot):
    steps = excitation_plan((35.0,), units=[0])
    times = np.arange(0, 0.3, 0.002)
    with pytest.raises(InvalidInputError, match="does not cover"):
        identify_units(steps, AMPLITUDE, paper_pose(robot), times, np.zeros((times.size, 6)),
                       np.zeros((times.size, 3)), np.zeros((times.size, 3)))
