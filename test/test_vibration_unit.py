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

CONFIG = Path(__file__).resolve().parents[1] / "stewart_vibration" / "config"
DT = 0.0005  # the emulator's physics period (2 kHz)


def slider_rig(mass: float, stiffness) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """Six sliders of ``mass`` kg, each on a slide joint fixed to the world (a unit's test rig) with its
    flexure's ``stiffness`` (6,) N/m as MuJoCo's joint spring (as in the robot's model), semi-implicit Euler
    at DT, no gravity."""
    bodies = "".join(
        f'<body name="slider_{i}" pos="{0.1 * i} 0 0"><joint name="unit_{i}" type="slide" axis="0 0 1" '
        f'stiffness="{float(k)!r}" springref="0"/>'
        f'<inertial pos="0 0 0" mass="{mass!r}" diaginertia="1e-4 1e-4 1e-4"/></body>' for i, k in enumerate(stiffness))
    motors = "".join(f'<motor joint="unit_{i}" gear="1"/>' for i in range(6))
    xml = (f'<mujoco><option timestep="{DT!r}" integrator="Euler" gravity="0 0 0"/>'
           f'<worldbody>{bodies}</worldbody><actuator>{motors}</actuator></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    return model, mujoco.MjData(model)


def run_rig(hw, demand: np.ndarray, load_n=None, start_loaded: bool = False) -> np.ndarray:
    """Drive the six units of ``hw`` on the rig with ``demand`` (n,) m for every unit; constant external
    force ``load_n`` (6,) N on each slider; returns the sliders' displacements (n, 6) m."""
    model, data = slider_rig(hw.rated_mass_kg, hw.stiffness_n_m)
    load = np.zeros(6) if load_n is None else np.asarray(load_n, float)
    loop = UnitLoop(hw)
    if start_loaded:
        loop.reset(holding_force=-load)
    data.qfrc_applied[:] = load
    out = np.empty((demand.size, 6))
    for n, d in enumerate(demand):
        x, v = data.qpos.copy(), data.qvel.copy()
        out[n] = x
        data.ctrl[:] = loop.coil_force(np.full(6, d), x) - hw.damping_n_s_m * v  # the flexure's damping
        mujoco.mj_step(model, data)
    return out


@pytest.fixture(scope="module")
def hardware(robot):
    plant = load_plant(CONFIG / "plant_realistic.yaml", robot)
    return unit_hardware(plant.units, robot.leg.vibration_unit_mass, DT)


def test_the_units_differ_and_their_drive_is_stable(hardware):
    assert np.ptp(hardware.stiffness_n_m) > 0 and np.ptp(hardware.force_constant_error) > 0
    # a step settles: 5 s after a 10 um step every unit is within 1 nm of it (the integral is slow)
    x = run_rig(hardware, np.full(int(5.0 / DT), 1e-5))
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
    """The static leg force at home (Newton-Euler, the platform's weight) pushes each slider, the drive started
    holding it (as the emulator starts its units): the mean over 1 s of a 35 Hz, 30 um vibration is within
    1 um of the demand's mean (acceptance). From a cold start (the drive at zero force) the integral takes the
    load over: within 1 um after 4 s."""
    static = leg_forces(robot, robot.home_pose, np.zeros(6), np.zeros(6))
    assert np.all(np.abs(static) > 1.0)  # a real load: newtons on each unit
    t = np.arange(int(5.0 / DT)) * DT
    demand = 5e-6 + 3e-5 * np.sin(2 * np.pi * 35.0 * t)
    # the platform's weight on the slider: minus the leg force
    warm = run_rig(hardware, demand[:int(1.0 / DT)], load_n=-static, start_loaded=True)
    assert np.all(np.abs(warm.mean(axis=0) - demand[:int(1.0 / DT)].mean()) < 1e-6), warm.mean(axis=0)
    cold = run_rig(hardware, demand, load_n=-static)
    last = t >= 4.0
    assert np.all(np.abs(cold[last].mean(axis=0) - demand[last].mean()) < 1e-6), cold[last].mean(axis=0)
    assert np.all(np.abs(cold[: int(0.2 / DT)].mean(axis=0) - 5e-6) > 1e-6)  # it did sag at first


def test_a_loaded_unit_started_with_its_holding_force_does_not_move(robot, hardware):
    static = leg_forces(robot, robot.home_pose, np.zeros(6), np.zeros(6))
    x = run_rig(hardware, np.zeros(int(0.5 / DT)), load_n=-static, start_loaded=True)
    assert np.all(np.abs(x).max(axis=0) < 1e-9)
    cold = run_rig(hardware, np.zeros(int(0.5 / DT)), load_n=-static)
    assert np.all(np.abs(cold).max(axis=0) > 1e-6)  # the check can see a sag: a cold start does move


def test_the_ideal_plant_has_no_unit_dynamics(robot):
    plant = load_plant(CONFIG / "plant_ideal.yaml", robot)
    assert plant.units.model == "ideal"


def passive_robot(robot, hardware, damped: bool):
    """The robot as built with its units as sliders (mjcf ``units``), every actuator off, RK4 at 0.1 ms,
    struts held at home by springs (20 kN/m, a stand-in for the servos), the flexures' springs and, if
    ``damped``, their damping as MuJoCo joint damping; every joint given a random velocity."""
    from stewart_vibration.sim.mjcf import SimulationSettings, UnitSliders, build_model

    model = build_model(robot, SimulationSettings(), units=UnitSliders(hardware.moving_mass_kg,
                                                                        tuple(hardware.stiffness_n_m)))
    model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    legs = [model.joint(f"leg_{i}").id for i in range(1, 7)]
    units = [model.joint(f"vib_{i}").id for i in range(1, 7)]
    for j in legs:
        model.jnt_stiffness[j] = 2e4
        model.qpos_spring[model.jnt_qposadr[j]] = model.qpos0[model.jnt_qposadr[j]]
    unit_dofs = np.array([model.jnt_dofadr[j] for j in units])
    model.dof_damping[unit_dofs] = hardware.damping_n_s_m if damped else 0.0
    data = mujoco.MjData(model)
    data.qvel[[model.jnt_dofadr[j] for j in units + legs]] = np.random.default_rng(0).normal(size=12) * 0.01
    mujoco.mj_forward(model, data)
    return model, data, unit_dofs


def energy_balance(robot, hardware, damped: bool) -> tuple[float, float, float]:
    """(energy change, the flexures' damping work, peak kinetic energy) over 0.5 s (J)."""
    model, data, dofs = passive_robot(robot, hardware, damped)
    c = hardware.damping_n_s_m if damped else np.zeros(6)
    start, work, peak = data.energy.sum(), 0.0, 0.0
    for _ in range(5000):
        before = -np.sum(c * data.qvel[dofs] ** 2)
        mujoco.mj_step(model, data)
        work += 0.5 * (before - np.sum(c * data.qvel[dofs] ** 2)) * model.opt.timestep
        peak = max(peak, data.energy[1])
    return data.energy.sum() - start, work, peak


def test_the_robot_with_unit_sliders_keeps_its_power_balance(robot):
    """Loops and damping off, the passive model conserves energy (kinetic + gravity + springs) to 0.5 % of
    its peak kinetic energy over 0.5 s; with the flexures' damping the energy lost is the damping's work
    (trapezoid rule on the step ends), and the same bound would miss that loss (the check can fail)."""
    plant = load_plant(CONFIG / "plant_realistic.yaml", robot)
    hardware = unit_hardware(plant.units, robot.leg.vibration_unit_mass, 1e-4)
    change, _, peak = energy_balance(plant.robot, hardware, damped=False)
    assert abs(change) < 0.005 * peak, (change, peak)
    change, work, peak = energy_balance(plant.robot, hardware, damped=True)
    assert abs(change - work) < 0.005 * peak, (change, work, peak)
    assert abs(change) > 0.1 * peak  # the damping takes a real share: without its work the balance fails
