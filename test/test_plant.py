"""The plant description (emulation/plant.py): the robot as built, drawn reproducibly from a seed within the
plant file's bounds, overrides that win, one clear error per bad value, and each unit's documented response."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from stewart_vibration.emulation.plant import load_plant, plant_from_dict
from stewart_vibration.errors import ConfigError

CONFIG = Path(__file__).resolve().parents[1] / "stewart_vibration" / "config"
REALISTIC = CONFIG / "plant_realistic.yaml"


def realistic_tree() -> dict:
    return yaml.safe_load(REALISTIC.read_text())


def test_one_seed_gives_one_plant_and_another_seed_another(robot):
    a, b = load_plant(REALISTIC, robot), load_plant(REALISTIC, robot)
    other = load_plant(REALISTIC, robot, seed=2)
    assert np.array_equal(a.robot.base_hinges, b.robot.base_hinges)
    assert np.array_equal(a.units.resonance_hz, b.units.resonance_hz)
    assert np.array_equal(a.sensors.load_cell_offsets_n, b.sensors.load_cell_offsets_n)
    assert other.seed == 2 and not np.allclose(other.robot.base_hinges, a.robot.base_hinges)
    assert not np.allclose(other.units.resonance_hz, a.units.resonance_hz)


def test_the_drawn_errors_fill_their_bounds_and_stay_inside(robot):
    tree = realistic_tree()
    for seed in range(10):
        plant = plant_from_dict(dict(tree, seed=seed), robot)
        hinges = np.concatenate([plant.base_hinge_errors, plant.platform_hinge_errors])
        assert np.abs(hinges).max() <= 0.0005 and np.abs(hinges).max() > 0.0004  # 36 draws reach the bound
        assert np.abs(plant.strut_zero_offsets).max() <= 0.0002
        assert abs(plant.robot.payload.mass / robot.payload.mass - 1.0) <= 0.20
        assert np.abs(plant.robot.payload.com - robot.payload.com).max() <= 0.010
        assert np.all(np.abs(plant.units.resonance_hz / 60.0 - 1.0) <= 0.20)
        assert np.all(np.abs(plant.units.gain - 1.0) <= 0.20)
        assert np.abs(plant.sensors.load_cell_offsets_n).max() <= 0.5
    assert np.array_equal(plant.nominal.base_hinges, robot.base_hinges)  # the drawing itself is untouched


def test_overrides_win_over_the_drawn_values(robot):
    offsets = [0.0001, -0.0001, 0.0, 0.0, 0.00005, 0.0]
    resonance = [55.0, 60.0, 65.0, 58.0, 62.0, 60.0]
    errors = np.zeros((6, 3))
    errors[2] = [0.0003, -0.0002, 0.0001]
    tree = dict(realistic_tree(), overrides={"strut_zero_offsets_m": offsets, "unit_resonance_hz": resonance,
                                             "base_hinge_errors_m": errors.tolist(), "payload_mass_kg": 2.0})
    plant = plant_from_dict(tree, robot)
    assert np.array_equal(plant.strut_zero_offsets, offsets) and np.array_equal(plant.units.resonance_hz, resonance)
    assert np.allclose(plant.base_hinge_errors, errors, atol=1e-15) and plant.robot.payload.mass == 2.0
    assert np.allclose(plant.robot.payload.inertia, robot.payload.inertia * 2.0 / robot.payload.mass)


def test_the_ideal_plant_is_the_drawing(robot):
    plant = load_plant(CONFIG / "plant_ideal.yaml", robot)
    assert plant.kind == "ideal" and plant.units.model == "ideal" and plant.struts.model == "ideal"
    assert np.array_equal(plant.robot.base_hinges, robot.base_hinges)
    assert np.array_equal(plant.robot.platform_hinges, robot.platform_hinges)
    assert plant.robot.payload.mass == robot.payload.mass and not plant.strut_zero_offsets.any()
    s = plant.sensors
    assert s.encoder_quantization_m == s.unit_sensor_noise_m == s.load_cell_noise_n == 0.0
    assert not s.load_cell_offsets_n.any() and not s.accel_bias_m_s2.any()


@pytest.mark.parametrize("change, key", [
    ({"plant": "perfect"}, "'plant'"),
    ({"seed": 1.5}, "'seed'"),
    ({"colour": "red"}, "colour"),
    ({"geometry": {"hinge_error_max_m": 0.5}}, "geometry.hinge_error_max_m"),
    ({"geometry": {"hinge_error_max_mm": 0.5}}, "hinge_error_max_mm"),
    ({"vibration_units": {"resonance_hz": 377e1}}, "vibration_units.resonance_hz"),
    ({"vibration_units": {"damping_ratio": "low"}}, "vibration_units.damping_ratio"),
    ({"vibration_units": {"model": "voice coil"}}, "vibration_units.model"),
    ({"vibration_units": {"suspension_damping_ratio": 0.3}}, "vibration_units.suspension_damping_ratio"),
    ({"vibration_units": {"rated_load_kg": -1.0}}, "vibration_units.rated_load_kg"),
    ({"struts": {"bandwidth_hz": float("nan")}}, "struts.bandwidth_hz"),
    ({"sensors": {"imu": {"accel_bias_max_m_s2": -1.0}}}, "sensors.imu.accel_bias_max_m_s2"),
    ({"sensors": {"tracker": []}}, "tracker"),
    ({"overrides": {"strut_zero_offsets_m": [0.0] * 5}}, "overrides.strut_zero_offsets_m"),
    ({"overrides": {"strut_zero_offsets_m": [0.1, 0, 0, 0, 0, 0]}}, "overrides.strut_zero_offsets_m[0]"),
    ({"overrides": {"base_hinge_errors_m": [[0.0, 0.0]] * 6}}, "overrides.base_hinge_errors_m[0]"),
])
def test_a_bad_value_is_one_error_naming_its_key(robot, change, key):
    with pytest.raises(ConfigError) as refused:
        plant_from_dict(dict(realistic_tree(), **change), robot, "plant.yaml")
    assert key in str(refused.value) and "plant.yaml" in str(refused.value)


def test_no_controller_node_imports_the_plant():
    """Kinematics, the planner, the estimator and the planning UI know only the nominal robot: importing any
    of them (and all they import) does not load the plant description."""
    controllers = ["kinematics_node", "vibration_planner_node", "leg_force_estimator_node", "planning_ui_node"]
    code = ("import importlib, sys\n"
            f"for name in {controllers!r}:\n"
            "    importlib.import_module('stewart_vibration.nodes.' + name)\n"
            "print('stewart_vibration.emulation.plant' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "False"
    emulator = subprocess.run([sys.executable, "-c", "import sys, stewart_vibration.emulation.plant; print(1)"],
                              capture_output=True, text=True, timeout=60)
    assert emulator.stdout.strip() == "1"  # the check can see the module when it is imported
