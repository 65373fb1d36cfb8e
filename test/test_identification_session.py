"""vibration.identification_session: what an identification goal may ask (refusals with their reason), the
windows a run streams (each step once, when due, starting and ending at rest), and the join of the two
sensor streams by stamp, checked against identification_run.identify_units on the same record (an
in-process emulator run)."""

from __future__ import annotations

import os

import numpy as np
import pytest
from emulator_runs import move_and_settle

from stewart_vibration.emulation.control_bench import run_excitation
from stewart_vibration.emulation.emulator import HardwareEmulator
from stewart_vibration.errors import InvalidInputError, VibrationLimitError
from stewart_vibration.output_files import writable_output
from stewart_vibration.paper import paper_pose
from stewart_vibration.sim.mjcf import load_simulation_settings
from stewart_vibration.vibration.identification_run import THERAPY_BAND_HZ, identify_units
from stewart_vibration.vibration.identification_session import (
    DEFAULT_AMPLITUDE_M,
    MAX_RUN_S,
    IdentificationSession,
    identification_steps,
)


@pytest.mark.parametrize("frequencies, amplitude, why", [
    ((35.0,), -1e-6, "amplitude_m"),
    ((35.0,), float("nan"), "amplitude_m"),
    ((35.0,), 60e-6, "half the units' travel"),
    ((35.0, 30.0), 0.0, "increasing"),
    ((35.0, 35.0), 0.0, "distinct"),
    ((35.0, float("inf")), 0.0, "band"),
    ((500.0,), 0.0, "band"),
    ((0.3,), 0.0, "would take"),  # 12 periods of 3.3 s for each of six units
])
def test_a_goal_outside_what_a_run_may_do_is_refused_with_its_reason(robot, frequencies, amplitude, why):
    with pytest.raises(InvalidInputError, match=why):
        identification_steps(frequencies, amplitude, robot.vibration_unit)


def test_a_demand_past_a_units_acceleration_limit_is_refused(robot):
    unit = robot.vibration_unit
    frequency = 0.9 * unit.frequency_max
    amplitude = 0.45 * unit.amplitude_max
    assert amplitude * (2 * np.pi * frequency) ** 2 > unit.acceleration_max  # the premise, from the limits
    with pytest.raises(VibrationLimitError):
        identification_steps((frequency,), amplitude, unit)


def test_the_default_run_covers_the_therapy_band_one_unit_at_a_time(robot):
    steps, amplitude = identification_steps((), 0.0, robot.vibration_unit)
    assert amplitude == DEFAULT_AMPLITUDE_M
    assert [(s.frequency, s.unit) for s in steps] == [(f, u) for f in THERAPY_BAND_HZ for u in range(6)]
    assert all(a.end < b.start for a, b in zip(steps, steps[1:]))  # one unit at a time, rest between
    assert steps[-1].end <= MAX_RUN_S


def test_the_output_must_be_a_writable_yaml_file_that_clobbers_nothing_else(tmp_path):
    def own(tree):
        return tree.get("kind") == "mine"

    assert writable_output(str(tmp_path / "units.yaml"), "test file", own) == tmp_path / "units.yaml"
    with pytest.raises(InvalidInputError, match="writable"):
        writable_output(str(tmp_path / "missing" / "units.yaml"), "test file", own)
    (tmp_path / "dir.yaml").mkdir()
    with pytest.raises(InvalidInputError, match="not a file"):
        writable_output(str(tmp_path / "dir.yaml"), "test file", own)
    with pytest.raises(InvalidInputError, match="YAML file"):
        writable_output("/etc/passwd", "test file", own)  # not a .yaml name: refused before it is looked at
    (tmp_path / "other.yaml").write_text("robot: something else\n")
    (tmp_path / "binary.yaml").write_bytes(b"\xff\xfe\x00")
    for name in ("other.yaml", "binary.yaml"):
        with pytest.raises(InvalidInputError, match="not overwritten"):
            writable_output(str(tmp_path / name), "test file", own)
    (tmp_path / "again.yaml").write_text("kind: mine\n")  # one of its own, written before: may be replaced
    assert writable_output(str(tmp_path / "again.yaml"), "test file", own) == tmp_path / "again.yaml"
    (tmp_path / "link.yaml").symlink_to(tmp_path / "again.yaml")  # never written through a link
    with pytest.raises(InvalidInputError, match="not overwritten"):
        writable_output(str(tmp_path / "link.yaml"), "test file", own)
    if os.geteuid() != 0:  # root writes anywhere
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o500)
        with pytest.raises(InvalidInputError):
            writable_output(str(locked / "units.yaml"), "test file", own)


def test_each_step_is_streamed_once_when_due_from_rest_to_rest(robot):
    steps, amplitude = identification_steps((30.0, 40.0), 0.0, robot.vibration_unit)
    session = IdentificationSession(steps, amplitude, robot.home_pose)
    assert list(session.due_windows(-1.0, 0.2)) == []  # nothing before its lead
    first = list(session.due_windows(-0.1, 0.2))
    assert [w[0] for w in first] == [steps[0].start]
    assert list(session.due_windows(-0.1, 0.2)) == []  # never twice
    later = list(session.due_windows(steps[5].start - 0.1, 0.2))
    assert [w[0] for w in later] == [s.start for s in steps[1:6]]
    for _, times, position, velocity, _ in first + later:
        assert np.all(np.diff(times) > 0) and times[0] == 0.0
        assert np.abs(position[[0, -1]]).max() < 1e-12 and np.abs(velocity[[0, -1]]).max() < 1e-9
    step, total, unit, frequency = session.progress(steps[7].start + 0.1)
    assert (step, total, unit, frequency) == (8, 12, steps[7].unit + 1, 40.0)


@pytest.mark.slow
def test_the_streams_joined_by_stamp_identify_what_the_record_does(robot):
    """Samples of one stream whose stamp the other lacks are left out: garbage there changes nothing."""
    emu = HardwareEmulator(robot, load_simulation_settings(timestep=1 / 2000))
    pose = paper_pose(robot)
    move_and_settle(emu, robot, pose)
    steps, amplitude = identification_steps((35.0,), 0.0, robot.vibration_unit)
    rec = run_excitation(emu, steps, amplitude)
    direct = identify_units(steps, amplitude, pose, rec["times"], rec["units"], rec["accel"], rec["gyro"],
                            gravity=robot.gravity, accel_average_s=0.002, unit_sensor_latency_s=0.0, provenance={})
    session = IdentificationSession(steps, amplitude, pose)
    for t, units, accel, gyro in zip(rec["times"], rec["units"], rec["accel"], rec["gyro"]):
        session.add_imu(t, accel, gyro)
        session.add_units(t, units)
        session.add_units(t + 0.0005, np.full(6, 1.0))  # a unit stamp the IMU never had
    joined = session.identification(robot.gravity, 0.002, 0.0, {})
    np.testing.assert_allclose(joined.unit_response, direct.unit_response, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(joined.platform_response, direct.platform_response, rtol=1e-9, atol=1e-12)
