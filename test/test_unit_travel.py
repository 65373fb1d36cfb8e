"""The vibration units' travel protection: the pure guard, and the robot as built ramping a vibration out when
a unit driven at its resonance leaves its travel (the controller sent nothing wrong: its demand was in range)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from emulator_runs import PERIOD, move_and_settle, start_tibia_vibration

from stewart_vibration.emulation.emulator import HardwareEmulator
from stewart_vibration.emulation.plant import load_plant
from stewart_vibration.emulation.unit_travel import UNIT_OVER_TRAVEL, UnitTravelGuard
from stewart_vibration.paper import paper_pose
from stewart_vibration.sim.mjcf import load_simulation_settings

CONFIG = Path(__file__).resolve().parents[1] / "stewart_vibration" / "config"
TRAVEL = 100e-6


def test_the_guard_trips_once_per_excursion_naming_the_unit():
    guard = UnitTravelGuard(TRAVEL)
    assert guard.check(np.full(6, 99e-6)) is None
    reading = np.array([0.0, 0.0, -101.5e-6, 50e-6, 0.0, 0.0])
    reason = guard.check(reading)
    assert reason is not None and reason.startswith(UNIT_OVER_TRAVEL) and "vib_3" in reason and "101.5" in reason
    assert guard.check(reading * 1.2) is None  # still outside: the ramp is already under way
    assert guard.check(np.zeros(6)) is None  # back inside: re-armed
    assert guard.check(reading) is not None and guard.trips == 2


def test_a_non_finite_reading_is_outside_the_travel():
    reason = UnitTravelGuard(TRAVEL).check([0.0, np.nan, 0.0, 0.0, 0.0, 0.0])
    assert reason is not None and "vib_2" in reason


@pytest.mark.parametrize("travel", [0.0, -1e-4, np.nan, np.inf])
def test_a_travel_that_is_not_a_positive_length_is_refused(travel):
    with pytest.raises(ValueError, match="unit travel"):
        UnitTravelGuard(travel)


def test_a_unit_past_its_travel_ramps_the_vibration_out_and_the_struts_hold(robot):
    """The robot as built of seed 2 (its units' resonances 49-65 Hz) and an uncompensated 35 Hz, 0.3 g vibration:
    the resonant units amplify their in-range demands (43-60 um) past the 100 um travel within the first cycles.
    The robot ramps the vibration out on its own: the status names a unit, every unit's true displacement stays
    within 1.5x the travel and is under 1 um 1.5 s after the start, and the platform stays where the struts
    hold it (within 50 um)."""
    plant = load_plant(CONFIG / "plant_realistic.yaml", robot, seed=2)
    emu = HardwareEmulator(robot, load_simulation_settings(timestep=1 / 2000), plant=plant)
    pose = paper_pose(robot)
    move_and_settle(emu, robot, pose)
    held = emu.platform_pose()
    _, t0 = start_tibia_vibration(emu, robot, pose)
    peak, tripped_at = 0.0, None
    while emu.time < t0 + 1.5:
        emu.advance(PERIOD)
        peak = max(peak, float(np.abs(emu.drive.unit_displacements()).max()))
        if tripped_at is None and emu.travel.trips:
            tripped_at = emu.time
    report, _ = emu.safety.vibration_report(emu.time)
    assert tripped_at is not None and tripped_at < t0 + 0.5, tripped_at
    assert report.state == "stopped" and report.ramp_reason.startswith(UNIT_OVER_TRAVEL), report
    assert report.event == "safety_ramp" and report.event_outcome == "UNIT_TRAVEL_STOPPED", report
    assert re.search(r"vib_[1-6] read 1\d\d\.\d um", report.ramp_reason), report.ramp_reason
    assert TRAVEL < peak < 1.5 * TRAVEL, peak
    assert np.abs(emu.drive.unit_displacements()).max() < 1e-6
    assert np.abs(emu.platform_pose()[:3] - held[:3]).max() < 50e-6
    assert not emu.safety.estopped and emu.fault is None  # a vibration stop, not an e-stop


def test_a_plant_whose_units_stay_within_their_travel_never_trips(robot):
    """Seed 1 (resonances 52-68 Hz): the same vibration keeps every unit under its travel (96 um at worst), and
    the guard leaves it alone."""
    plant = load_plant(CONFIG / "plant_realistic.yaml", robot, seed=1)
    emu = HardwareEmulator(robot, load_simulation_settings(timestep=1 / 2000), plant=plant)
    pose = paper_pose(robot)
    move_and_settle(emu, robot, pose)
    _, t0 = start_tibia_vibration(emu, robot, pose, duration_s=1.0)
    peak = 0.0
    while emu.time < t0 + 0.8:
        emu.advance(PERIOD)
        peak = max(peak, float(np.abs(emu.drive.unit_displacements()).max()))
    assert 50e-6 < peak < TRAVEL and emu.travel.trips == 0, (peak, emu.travel.trips)
    assert emu.safety.vibration_report(emu.time)[0].state == "running"
