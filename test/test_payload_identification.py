"""The payload and the load cells' offsets identified from the cells at rest (estimation.payload_identification):
against the Newton-Euler forces of a robot carrying another payload (closed loop of the model), against MuJoCo
on the drawing and on the robot as built (the plant file's truth, which only this test reads), and through the
calibrated robot file into the force estimator's wrench."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from stewart_vibration import load_robot
from stewart_vibration.calibration.identification import identify
from stewart_vibration.calibration.measurement_model import TrackerNoise
from stewart_vibration.calibration.pose_plan import plan_calibration_poses, reachable_candidates
from stewart_vibration.calibration.robot_file import calibrated_tree, dump_robot_file
from stewart_vibration.dynamics.newton_euler import leg_forces
from stewart_vibration.emulation.calibration_bench import measure_poses
from stewart_vibration.emulation.emulator import HardwareEmulator
from stewart_vibration.emulation.plant import load_plant
from stewart_vibration.errors import CalibrationError, ConfigError
from stewart_vibration.estimation import ForceEstimator
from stewart_vibration.estimation.payload_identification import calibrated_load, identify_payload
from stewart_vibration.install import default_config_dir
from stewart_vibration.kinematics.rotations import rotation_from_rpy
from stewart_vibration.robot import RigidBody, drawing_tree, robot_from_dict
from stewart_vibration.safe_yaml import load_yaml
from stewart_vibration.sim.mjcf import load_simulation_settings

ROBOT = load_robot()
PLANT_FILE = default_config_dir() / "plant_realistic.yaml"


def workspace_poses(count: int, seed: int = 3) -> np.ndarray:
    return reachable_candidates(ROBOT, count, 0.02, np.radians(15), np.random.default_rng(seed))


def at_rest(robot, poses: np.ndarray) -> np.ndarray:
    zero = np.zeros_like(poses)
    return leg_forces(robot, poses, zero, zero)


def test_another_payload_and_offset_cells_are_identified_exactly_from_the_model_at_rest():
    """Cells = the Newton-Euler forces at rest of the robot carrying a payload 20 % heavier with its centre of
    mass 6 mm off, plus constant offsets: the linear fit about the drawing's payload returns them to rounding."""
    payload = RigidBody(1.8, np.array([0.004, -0.006, 0.086]), ROBOT.payload.inertia * 1.2)
    offsets = np.array([0.3, -0.2, 0.45, -0.1, 0.0, 0.25])
    poses = workspace_poses(12)
    cells = at_rest(replace(ROBOT, payload=payload), poses) + offsets
    found = identify_payload(ROBOT, poses[:, :3], rotation_from_rpy(poses[:, 3:]), cells)
    assert found.mass_kg == pytest.approx(1.8, abs=1e-9)
    np.testing.assert_allclose(found.com_m, payload.com, atol=1e-9)
    np.testing.assert_allclose(found.load_cell_offsets_n, offsets, atol=1e-8)
    np.testing.assert_allclose(found.body.inertia, payload.inertia, rtol=1e-9)
    assert found.residual_rms_n < 1e-9


def test_cells_that_cannot_tell_the_payload_are_refused_with_a_reason():
    poses = workspace_poses(6)
    positions, rotations = poses[:, :3], rotation_from_rpy(poses[:, 3:])
    cells = at_rest(ROBOT, poses)
    with pytest.raises(CalibrationError, match="finite") as gaps:
        identify_payload(ROBOT, positions, rotations, np.where(np.eye(6, dtype=bool), np.nan, cells))
    assert gaps.value.reason == "BAD_DATA"
    with pytest.raises(CalibrationError, match="2 poses") as one:
        identify_payload(ROBOT, positions[:1], rotations[:1], cells[:1])
    assert one.value.reason == "TOO_FEW_POSES"
    same = np.repeat(poses[:1], 6, axis=0)  # one pose six times: the offsets are the payload's weight
    with pytest.raises(CalibrationError, match="undetermined") as flat:
        identify_payload(ROBOT, same[:, :3], rotation_from_rpy(same[:, 3:]), at_rest(ROBOT, same))
    assert flat.value.reason == "UNIDENTIFIABLE"


def bench(plant, count: int = 20):
    """The calibration's poses measured on the emulator of ``plant`` (None: the drawing) at rest."""
    emu = HardwareEmulator(ROBOT, load_simulation_settings(timestep=1 / 2000), plant=plant)
    noise = TrackerNoise(2e-5, np.radians(0.005))
    return measure_poses(emu, plan_calibration_poses(ROBOT, count, 60, noise), settle_s=0.3, window_s=1.0), noise


def test_on_the_drawing_the_payload_is_the_drawings_and_the_cells_have_no_offset():
    measured, _ = bench(None, 14)
    found = identify_payload(ROBOT, measured.data.positions, measured.data.rotations, measured.loads)
    print("drawing:", found.mass_kg, found.com_m, found.load_cell_offsets_n, found.residual_rms_n)
    assert found.mass_kg == pytest.approx(ROBOT.payload.mass, rel=2e-3)
    np.testing.assert_allclose(found.com_m, ROBOT.payload.com, atol=2e-4)
    np.testing.assert_allclose(found.load_cell_offsets_n, 0.0, atol=5e-3)


def test_on_the_robot_as_built_the_cells_give_its_payload_and_their_offsets_and_the_model_matches_them(tmp_path):
    """Realistic plant, seed 1 (payload 3.7 % heavier than drawn, centre of mass 5-7 mm off; cells offset up to
    0.5 N, 0.05 N noise): identified on the calibrated geometry, the payload's mass is within 3 % and its
    centre of mass within 0.5 mm across and 2.5 mm along the tibia axis, the offsets within 0.08 N (the mass and
    a common offset nearly trade against each other at rest: the legs' common load barely changes over the
    workspace). The model with them explains the cells at rest to 0.02 N RMS, where the drawing's payload
    without offsets leaves 0.2 N and more; through the robot file the force estimator's wrench at rest (no
    tissue: all of it is error) falls from 0.7 N to below 0.15 N."""
    plant = load_plant(PLANT_FILE, ROBOT, seed=1)
    measured, noise = bench(plant)
    fit = identify(ROBOT, measured.data, noise)
    load, said = calibrated_load(ROBOT, fit, measured.data, measured.loads)
    print(said)
    assert load is not None
    truth = plant.robot.payload
    found = load["payload_identified"]
    assert abs(found["mass_kg"] / truth.mass - 1) < 0.03 < abs(ROBOT.payload.mass / truth.mass - 1)
    np.testing.assert_allclose(found["com_m"][:2], truth.com[:2], atol=5e-4)
    assert abs(found["com_m"][2] - truth.com[2]) < 2.5e-3
    np.testing.assert_allclose(load["load_cells"]["offsets_n"], plant.sensors.load_cell_offsets_n, atol=0.08)

    tree = calibrated_tree(load_yaml(default_config_dir() / "robot.yaml", "robot config"), fit, {}, load)
    path = tmp_path / "robot_calibrated.yaml"
    path.write_text(dump_robot_file(tree))
    calibrated = load_robot(path)
    assert calibrated.calibrated and calibrated.payload.mass == pytest.approx(found["mass_kg"])
    np.testing.assert_allclose(calibrated.load_cell_offsets, load["load_cells"]["offsets_n"])
    drawn = robot_from_dict(drawing_tree(load_yaml(path, "robot config")))
    assert drawn.payload.mass == ROBOT.payload.mass and not drawn.load_cell_offsets.any()

    poses = measured.truth
    leftover = {"drawing": measured.loads - at_rest(ROBOT, poses),
                "calibrated": measured.loads - calibrated.load_cell_offsets - at_rest(calibrated, poses)}
    rms = {name: float(np.sqrt(np.mean(x ** 2))) for name, x in leftover.items()}
    wrench = {}
    for name, robot in (("drawing", ROBOT), ("calibrated", calibrated)):
        estimator = ForceEstimator(robot)
        lengths = np.asarray(measured.data.readings) - robot.strut_zero_offsets  # what the encoders read
        est = estimator.estimate(np.arange(len(poses)) * 0.002, lengths, np.zeros_like(lengths), np.zeros_like(
            lengths), np.zeros_like(lengths), measured.loads)
        wrench[name] = float(np.median(np.linalg.norm(est.wrench[:, :3], axis=1)))
    print("cells left unexplained at rest (RMS N):", rms, "wrench at rest (median |F| N):", wrench)
    assert rms["calibrated"] < 0.02 and rms["drawing"] > 0.2
    assert wrench["calibrated"] < 0.15 and wrench["drawing"] > 4 * wrench["calibrated"]


def test_a_robot_file_with_broken_load_cells_is_refused_by_name():
    tree = load_yaml(default_config_dir() / "robot.yaml", "robot config")
    with pytest.raises(ConfigError, match="load_cells.offsets_n"):
        robot_from_dict({**tree, "load_cells": {"offsets_n": [0.0, 0.0, 0.0, 0.0, 0.0, 500.0]}})
    with pytest.raises(ConfigError, match="'load_cells' must be a mapping"):
        robot_from_dict({**tree, "load_cells": 3})
