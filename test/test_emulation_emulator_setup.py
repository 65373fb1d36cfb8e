"""The emulator built from its node's parameters (emulation.emulator_setup) without ROS: the names are the
node's parameters, the defaults build the drawn robot at the physics rate from the run's clock, a plant
seed of -1 keeps the file's, a missing file fails, and the live parameters reach the vibration buffer."""

from __future__ import annotations

import inspect

import pytest

from stewart_vibration.emulation.emulator_setup import (
    LIVE_PARAMETERS,
    SETUP_PARAMETERS,
    build_emulator,
    set_live_parameter,
)
from stewart_vibration.errors import StewartError
from stewart_vibration.parameters.tables import HARDWARE_EMULATOR

SPECS = {spec.name: spec for spec in HARDWARE_EMULATOR}
DEFAULTS = {name: SPECS[name].default for name in SETUP_PARAMETERS}


@pytest.fixture(autouse=True)
def in_tmp_path(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo may write MUJOCO_LOG.TXT in the working directory


def test_the_names_are_the_nodes_parameters_read_at_configure_or_live():
    keywords = [p for p in inspect.signature(build_emulator).parameters if p != "start_time"]
    assert sorted(keywords) == sorted(SETUP_PARAMETERS)
    assert set(SETUP_PARAMETERS) <= set(SPECS)
    assert all(SPECS[name].at_configure or name in LIVE_PARAMETERS for name in SETUP_PARAMETERS if name in SPECS)
    assert all(not SPECS[name].at_configure and not SPECS[name].read_only for name in LIVE_PARAMETERS)


def test_the_defaults_build_the_drawn_robot_at_the_physics_rate_from_the_runs_clock():
    setup = build_emulator(**DEFAULTS, start_time=12.5)
    assert setup.emulator.dt == pytest.approx(1.0 / SPECS["physics_rate_hz"].default)
    assert setup.emulator.time == 12.5
    assert setup.tissue is None and setup.plant is None
    assert not setup.robot.calibrated
    assert setup.summary().startswith(f"MuJoCo dt {setup.emulator.dt} s, ")
    assert setup.summary().endswith("tissue none, plant ideal")
    assert setup.facts() == {"servo_bandwidth_hz": setup.settings.servo_bandwidth_hz, "tissue": "none",
                             "plant": "ideal"}
    assert setup.emulator.vibration.watchdog_s == SPECS["watchdog_s"].default


def test_a_plant_seed_below_zero_keeps_the_files_and_one_above_replaces_it():
    own = build_emulator(**{**DEFAULTS, "plant_config": "realistic", "plant_seed": -1}, start_time=0.0)
    seeded = build_emulator(**{**DEFAULTS, "plant_config": "realistic", "plant_seed": 7}, start_time=0.0)
    assert seeded.plant.seed == 7 and own.plant.seed != 7
    assert seeded.facts()["plant"] == "realistic (seed 7)"
    assert f"plant realistic seed 7 ({seeded.plant.source})" in seeded.summary()


def test_a_missing_robot_file_fails_the_build(tmp_path):
    with pytest.raises((StewartError, OSError)):
        build_emulator(**{**DEFAULTS, "robot_config": str(tmp_path / "missing.yaml")}, start_time=0.0)


def test_the_live_parameters_set_the_vibration_buffer():
    emulator = build_emulator(**DEFAULTS, start_time=0.0).emulator
    set_live_parameter(emulator, "watchdog_s", 1.5)
    set_live_parameter(emulator, "vibration_ramp_s", 0.02)
    set_live_parameter(emulator, "max_lookahead_s", 60)
    buffer = emulator.vibration
    assert (buffer.watchdog_s, buffer.ramp_s, buffer.max_lookahead_s) == (1.5, 0.02, 60.0)
