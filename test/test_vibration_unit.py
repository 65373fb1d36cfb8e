"""The vibration unit as a physical actuator: its drive and sliders integrated by MuJoCo reproduce the
documented fixed-base response (an independent integrator, not the closed form's own algebra); a loaded
unit holds its mean position; the drive's state starts a loaded unit without a jump."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from stewart_vibration.dynamics import leg_forces
from stewart_vibration.emulation.plant import load_plant
from stewart_vibration.emulation.vibration_unit import UnitLoop, fixed_base_response, unit_hardware

CONFIG = Path(__file__).resolve().parents[1] / "config"
DT = 0.0005  # the emulator's physics period (2 kHz)


def slider_rig(mass: float) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """Six sliders of ``mass`` kg, each on a slide joint fixed to the world (a unit's test rig), semi-implicit
    Euler at DT, no gravity: forces on them are the actuators' alone."""
    bodies = "".join(
        f'<body name="slider_{i}" pos="{0.1 * i} 0 0"><joint name="unit_{i}" type="slide" axis="0 0 1"/>'
        f'<inertial pos="0 0 0" mass="{mass!r}" diaginertia="1e-4 1e-4 1e-4"/></body>' for i in range(6))
    motors = "".join(f'<motor joint="unit_{i}" gear="1"/>' for i in range(6))
    xml = (f'<mujoco><option timestep="{DT!r}" integrator="Euler" gravity="0 0 0"/>'
           f'<worldbody>{bodies}</worldbody><actuator>{motors}</actuator></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    return model, mujoco.MjData(model)


def run_rig(hw, demand: np.ndarray, load_n=None, start_loaded: bool = False) -> np.ndarray:
    """Drive the six units of ``hw`` on the rig with ``demand`` (n,) m for every unit; constant external
    force ``load_n`` (6,) N on each slider; returns the sliders' displacements (n, 6) m."""
    model, data = slider_rig(hw.rated_mass_kg)
    load = np.zeros(6) if load_n is None else np.asarray(load_n, float)
    loop = UnitLoop(hw)
    if start_loaded:
        loop.reset(holding_force=-load)
    data.qfrc_applied[:] = load
    out = np.empty((demand.size, 6))
    for n, d in enumerate(demand):
        x, v = data.qpos.copy(), data.qvel.copy()
        out[n] = x
        data.ctrl[:] = loop.coil_force(np.full(6, d), x) - hw.stiffness_n_m * x - hw.damping_n_s_m * v
        mujoco.mj_step(model, data)
    return out


@pytest.fixture(scope="module")
def hardware(robot):
    plant = load_plant(CONFIG / "plant_realistic.yaml", robot)
    return unit_hardware(plant.units, robot.leg.vibration_unit_mass, DT)


def test_the_units_differ_and_their_drive_is_stable(hardware):
    assert np.ptp(hardware.stiffness_n_m) > 0 and np.ptp(hardware.force_constant_error) > 0
    # a step settles: 2 s after a 10 um step every unit is within 1 nm of it
    x = run_rig(hardware, np.full(int(2.0 / DT), 1e-5))
    assert np.all(np.abs(x[-1] - 1e-5) < 1e-9) and np.all(np.abs(x).max(axis=0) < 1e-4)


def test_a_unit_on_its_rig_driven_by_a_sine_has_its_documented_response(hardware):
    """Amplitude within 1 % and phase within 0.5 deg at 10 frequencies from 5 to 120 Hz (acceptance),
    each unit integrated by MuJoCo; the fit uses the last 10 periods after the drive settled."""
    freqs = np.geomspace(5.0, 120.0, 10)
    documented = fixed_base_response(hardware, freqs)
    for k, f in enumerate(freqs):
        settle, measure = 1.0, 10.0 / f
        t = np.arange(int(round((settle + measure) / DT))) * DT
        demand = 2e-5 * np.sin(2 * np.pi * f * t)
        x = run_rig(hardware, demand)
        tail = t >= settle
        basis = np.column_stack([np.sin(2 * np.pi * f * t[tail]), np.cos(2 * np.pi * f * t[tail]),
                                 np.ones(tail.sum())])
        coef, *_ = np.linalg.lstsq(basis, x[tail], rcond=None)
        measured = (coef[0] + 1j * coef[1]) / 2e-5  # x = Im(H e^{jwt}) d0 = d0 (Re H sin + Im H cos)
        ratio = measured / documented[:, k]
        assert np.all(np.abs(np.abs(ratio) - 1) < 0.01), (f, np.abs(ratio))
        assert np.all(np.abs(np.degrees(np.angle(ratio))) < 0.5), (f, np.degrees(np.angle(ratio)))
    # and the response is a resonance, not a displacement source: at 35 Hz the units are off in amplitude
    at_35 = fixed_base_response(hardware, [35.0])[:, 0]
    assert np.ptp(np.abs(at_35)) > 0.1 and np.all(np.abs(np.angle(at_35)) > np.radians(5))


def test_a_unit_under_the_static_leg_force_of_the_home_pose_holds_its_mean_position(robot, hardware):
    """The static leg force at home (Newton-Euler, the platform's weight) pushes each slider; the
    integral takes it over: 1 s on, the mean over 1 s of a 35 Hz, 30 um vibration is within 1 um of the
    demand's mean (acceptance), from a cold start with the drive at zero force."""
    static = leg_forces(robot, robot.home_pose, np.zeros(6), np.zeros(6))
    assert np.all(np.abs(static) > 1.0)  # a real load: newtons on each unit
    t = np.arange(int(2.0 / DT)) * DT
    demand = 5e-6 + 3e-5 * np.sin(2 * np.pi * 35.0 * t)
    x = run_rig(hardware, demand, load_n=-static)  # the platform's weight on the slider: minus the leg force
    last = t >= 1.0
    assert np.all(np.abs(x[last].mean(axis=0) - demand[last].mean()) < 1e-6), x[last].mean(axis=0)


def test_a_loaded_unit_started_with_its_holding_force_does_not_move(robot, hardware):
    static = leg_forces(robot, robot.home_pose, np.zeros(6), np.zeros(6))
    x = run_rig(hardware, np.zeros(int(0.5 / DT)), load_n=-static, start_loaded=True)
    assert np.all(np.abs(x).max(axis=0) < 1e-9)
    cold = run_rig(hardware, np.zeros(int(0.5 / DT)), load_n=-static)
    assert np.all(np.abs(cold).max(axis=0) > 1e-6)  # the check can see a sag: a cold start does move


def test_the_ideal_plant_has_no_unit_dynamics(robot):
    plant = load_plant(CONFIG / "plant_ideal.yaml", robot)
    assert plant.units.model == "ideal"
