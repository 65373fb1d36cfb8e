"""Kinematic calibration: the measurement model against finite differences, the identification against the
plant file's truth (the emulated robot's sensors, in process), the calibrated robot file round trip, and a
refusal or a flag for each kind of bad data."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration import load_robot
from stewart_vibration.calibration.geometry_parameters import parameters_of, robot_with_parameters
from stewart_vibration.calibration.identification import CalibrationData, identify
from stewart_vibration.calibration.measurement_model import (
    TrackerNoise,
    parameter_jacobian,
    pose_sensitivity,
    predicted_readings,
)
from stewart_vibration.calibration.pose_average import average_window
from stewart_vibration.calibration.pose_plan import plan_calibration_poses, reachable_candidates
from stewart_vibration.calibration.robot_file import calibrated_tree, dump_robot_file
from stewart_vibration.emulation.calibration_bench import measure_poses, pose_errors
from stewart_vibration.emulation.emulator import HardwareEmulator
from stewart_vibration.emulation.plant import load_plant
from stewart_vibration.errors import CalibrationError, ConfigError
from stewart_vibration.install import default_config_dir
from stewart_vibration.kinematics import forward_kinematics, inverse_kinematics
from stewart_vibration.kinematics.rotations import rotation_from_rpy, so3_exp
from stewart_vibration.safe_yaml import load_yaml
from stewart_vibration.sim.mjcf import load_simulation_settings

ROBOT = load_robot()
PLANT_FILE = default_config_dir() / "plant_realistic.yaml"


def plant_truth(plant) -> np.ndarray:
    """The 42 parameters of the plant file's robot as built (what the controller never reads)."""
    return np.concatenate([plant.robot.base_hinges.ravel(), plant.robot.platform_hinges.ravel(),
                           plant.strut_zero_offsets])


def noise_of(plant) -> TrackerNoise:
    s = plant.sensors
    return TrackerNoise(s.tracker_position_noise_m, np.radians(s.tracker_orientation_noise_deg))


@pytest.fixture(scope="module")
def bench():
    """Seed 2 of the realistic plant: 40 planned poses measured, 12 validation poses in the reduction workspace."""
    plant = load_plant(PLANT_FILE, ROBOT, seed=2)
    emu = HardwareEmulator(ROBOT, load_simulation_settings(timestep=1 / 2000), plant=plant)
    noise = noise_of(plant)
    poses = plan_calibration_poses(ROBOT, 40, 30, noise)
    calibration = measure_poses(emu, poses, settle_s=0.2, window_s=0.5)
    validation = measure_poses(emu, reachable_candidates(ROBOT, 12, 0.02, np.radians(15), np.random.default_rng(7)),
                               settle_s=0.2, window_s=0.5)
    return plant, emu, noise, calibration, validation


def random_poses(count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    poses = reachable_candidates(ROBOT, count, 0.02, np.radians(10), np.random.default_rng(seed))
    return poses[:, :3], rotation_from_rpy(poses[:, 3:])


def test_the_parameter_jacobian_is_the_finite_difference_of_the_readings():
    positions, rotations = random_poses(5, 1)
    theta = parameters_of(ROBOT) + np.random.default_rng(2).normal(0, 3e-4, 42)
    jac = parameter_jacobian(theta, positions, rotations)
    step = 1e-7
    for p in range(42):
        e = np.zeros(42)
        e[p] = step
        fd = (predicted_readings(theta + e, positions, rotations) - predicted_readings(theta - e, positions,
                                                                                         rotations)) / (2 * step)
        np.testing.assert_allclose(jac[:, :, p], fd, atol=1e-7)


def test_the_pose_sensitivity_is_the_finite_difference_of_a_tracker_error():
    positions, rotations = random_poses(4, 3)
    theta = parameters_of(ROBOT)
    sens = pose_sensitivity(theta, positions, rotations)
    step = 1e-7
    for a in range(6):
        e = np.zeros(6)
        e[a] = step
        # a tracker error: the position moves, the rotation turns about the platform frame (R exp(nu))
        plus = predicted_readings(theta, positions + e[:3], rotations @ so3_exp(e[3:]))
        minus = predicted_readings(theta, positions - e[:3], rotations @ so3_exp(-e[3:]))
        np.testing.assert_allclose(sens[:, :, a], (plus - minus) / (2 * step), atol=1e-7)


def test_a_robot_with_strut_zero_offsets_reads_its_encoders_short_of_the_hinge_distance():
    theta = parameters_of(ROBOT)
    theta[36:] = [1e-4, -2e-4, 0.0, 5e-5, 0.0, -1e-4]
    robot = robot_with_parameters(ROBOT, theta)
    pose = ROBOT.home_pose + np.array([0.005, -0.003, 0.004, 0.05, -0.02, 0.1])
    hinge_to_hinge = inverse_kinematics(ROBOT, pose)  # same hinges, no offsets
    np.testing.assert_allclose(inverse_kinematics(robot, pose), hinge_to_hinge - theta[36:], atol=1e-12)
    fk = forward_kinematics(robot, inverse_kinematics(robot, pose))
    np.testing.assert_allclose(fk.pose, pose, atol=1e-10)


def test_calibration_recovers_the_plant_geometry_with_an_honest_covariance(bench):
    plant, _, noise, calibration, validation = bench
    result = identify(ROBOT, calibration.data, noise)
    assert not result.dropped and 0.5 < result.reduced_chi2 < 2.0, (result.dropped, result.reduced_chi2)
    z = (result.theta - plant_truth(plant)) / result.std
    assert np.abs(z).max() < 5.0, np.abs(z).max()
    calibrated = robot_with_parameters(ROBOT, result.theta)
    nominal_position, nominal_angle = pose_errors(ROBOT, validation.data.readings, validation.truth)
    position, angle = pose_errors(calibrated, validation.data.readings, validation.truth)
    assert nominal_position.max() > 2e-4  # the drawing is off by a fraction of a millimetre or more
    assert position.max() <= 50e-6 and np.degrees(angle.max()) <= 0.01, (position.max(), np.degrees(angle.max()))


def test_a_pose_with_a_2_mm_tracker_outlier_is_reported_and_dropped(bench):
    plant, _, noise, calibration, _ = bench
    data = calibration.data
    positions = data.positions.copy()
    positions[7, 1] += 2e-3
    result = identify(ROBOT, CalibrationData(positions, data.rotations, data.readings, data.frames), noise)
    assert [d.index for d in result.dropped] == [7] and not result.used[7]
    assert result.residual_rms_m[7] > 3e-4
    assert np.abs((result.theta - plant_truth(plant)) / result.std).max() < 5.0


def test_many_disagreeing_poses_are_refused_not_fitted(bench):
    _, _, noise, calibration, _ = bench
    data = calibration.data
    readings = data.readings.copy()
    readings[::3, 2] += 5e-4  # a third of the poses: a strut that slipped by 0.5 mm
    with pytest.raises(CalibrationError) as refusal:
        identify(ROBOT, CalibrationData(data.positions, data.rotations, readings, data.frames), noise)
    assert refusal.value.reason == "TOO_MANY_OUTLIERS" and refusal.value.outcome == "CALIBRATION_REJECTED"


def test_too_few_poses_are_refused(bench):
    _, _, noise, calibration, _ = bench
    with pytest.raises(CalibrationError) as refusal:
        identify(ROBOT, calibration.data.subset(np.arange(8)), noise)
    assert refusal.value.reason == "TOO_FEW_POSES" and "8 poses" in str(refusal.value)


def test_poses_that_never_turn_the_platform_are_refused_as_unidentifiable(bench):
    _, emu, noise, _, _ = bench
    poses = reachable_candidates(ROBOT, 20, 0.02, 0.0, np.random.default_rng(5))  # translations only
    measured = measure_poses(emu, poses, settle_s=0.1, window_s=0.2)
    with pytest.raises(CalibrationError) as refusal:
        identify(ROBOT, measured.data, noise)
    assert refusal.value.reason == "UNIDENTIFIABLE" and "hinge" in str(refusal.value)


def test_a_frozen_or_silent_tracker_is_refused():
    stamps = np.arange(60) / 60.0
    positions = np.random.default_rng(0).normal(0, 2e-5, (60, 3)) + [0, 0, 0.16]
    quaternions = np.tile([0.0, 0.0, 0.0, 1.0], (60, 1))
    readings = np.full((500, 6), 0.17)
    ok = average_window(stamps, positions, quaternions, readings, (0.0, 1.0), 60.0)
    assert ok.frames == 60 and np.allclose(ok.position, positions.mean(axis=0))
    frozen = np.tile(positions[0], (60, 1))  # the same frame again and again, fresh stamps
    for args in ((stamps, frozen), (np.zeros(60), positions), (stamps[:10], positions[:10])):
        with pytest.raises(CalibrationError) as refusal:
            average_window(args[0], args[1], quaternions[:len(args[0])], readings, (0.0, 1.0), 60.0)
        assert refusal.value.reason == "TRACKER_FROZEN"


def test_the_calibrated_robot_file_loads_as_the_identified_robot(bench, tmp_path):
    _, _, noise, calibration, _ = bench
    result = identify(ROBOT, calibration.data, noise)
    tree = calibrated_tree(load_yaml(default_config_dir() / "robot.yaml", "robot config"), result,
                           {"plant_seed_for_test": 2})
    path = tmp_path / "robot_calibrated.yaml"
    path.write_text(dump_robot_file(tree))
    loaded = load_robot(path)
    expected = robot_with_parameters(ROBOT, result.theta)
    assert loaded.calibrated and not ROBOT.calibrated
    for field in ("base_hinges", "platform_hinges", "strut_zero_offsets"):
        np.testing.assert_allclose(getattr(loaded, field), getattr(expected, field), atol=2e-9)
    assert load_yaml(path, "robot config")["calibration"]["poses_used"] == 40
    with pytest.raises(ConfigError, match="calibrated robot file"):
        load_plant(PLANT_FILE, loaded, seed=2)  # the emulated robot is built from the drawing only
