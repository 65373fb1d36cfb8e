"""The estimator's per-run state without ROS (issue 12): a batch gives the per-message forces sample for
sample, the commanded accelerations come from the emulator's own buffer (including its e-stop ramp),
and the modelled forces match what the emulator applied."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.emulation.emulator import HardwareEmulator
from stewart_vibration.emulation.strut_trajectory import build_trajectory
from stewart_vibration.estimation import ForceEstimator
from stewart_vibration.robot import VIB_NAMES
from stewart_vibration.sim.mjcf import load_simulation_settings
from stewart_vibration.vibration import decompose_vibration
from stewart_vibration.vibration.streaming import StreamSettings, VibrationStream


@pytest.fixture(scope="module")
def run(robot):
    """A 1.2 s vibration at home with an e-stop at 0.9 s; states every 2 ms and the window sent."""
    emu = HardwareEmulator(robot, load_simulation_settings(timestep=1 / 2000))
    plan = decompose_vibration(robot, robot.home_pose, [0.0, 0.0, 1.0], acceleration_g=0.3, frequency=35.0)
    t0 = 0.2
    window = VibrationStream(robot, plan, StreamSettings(duration=1.2)).next_window(-t0)
    traj = build_trajectory(VIB_NAMES, VIB_NAMES, t0, window.times, window.position, window.velocity,
                            window.acceleration)
    emu.command_vibration(VIB_NAMES, t0, window.times, window.position, window.velocity, window.acceleration)
    states = []
    estop = None
    while emu.time < 1.4:
        emu.advance(0.002)
        if estop is None and emu.time >= 0.9:
            emu.emergency_stop()
            estop = emu.time
        _, pos, vel, eff = emu.joint_state()
        states.append((emu.time, pos, vel, eff[:6]))
    return {"traj": traj, "states": states, "estop": estop, "report": emu.vibration_report()[0]}


def arrays(states):
    t = np.array([s[0] for s in states])
    pos, vel, eff = (np.array([s[k] for s in states]) for k in (1, 2, 3))
    return t, pos[:, :6], pos[:, 6:], vel[:, :6], vel[:, 6:], eff


def estimator(robot, run):
    est = ForceEstimator(robot)
    est.command_vibration(run["traj"], now=0.0)
    est.apply_ramp(run["report"].ramp_start, run["report"].ramp_reason)  # as the emulator reports the e-stop
    return est


def test_batch_equals_one_by_one(robot, run):
    t, struts, vib, strut_rates, vib_rates, eff = arrays(run["states"])
    whole = estimator(robot, run).estimate(t, struts, vib, strut_rates, vib_rates, eff)
    single = estimator(robot, run)
    one = [single.estimate(t[i:i + 1], struts[i:i + 1], vib[i:i + 1], strut_rates[i:i + 1], vib_rates[i:i + 1],
                           eff[i:i + 1]) for i in range(len(t))]
    assert whole.ok.all() and all(o.ok.all() for o in one)
    forces = np.concatenate([o.forces for o in one])
    wrench = np.concatenate([o.wrench for o in one])
    assert np.abs(whole.forces - forces).max() < 1e-12 * np.abs(forces).max()  # ~5.5 N: FK converged to 1e-14 m
    assert np.abs(whole.wrench - wrench).max() < 1e-12 * np.abs(forces).max()


def test_model_matches_the_emulator_through_the_estop(robot, run):
    t, struts, vib, strut_rates, vib_rates, eff = arrays(run["states"])
    est = estimator(robot, run).estimate(t, struts, vib, strut_rates, vib_rates, eff)
    vibrating = (t > 0.5) & (t < 0.85)
    amplitude = (eff[vibrating].max(axis=0) - eff[vibrating].min(axis=0)) / 2
    err = np.abs(est.forces - eff)
    assert (np.sqrt((err[vibrating] ** 2).mean(axis=0)) / amplitude).max() < 0.01
    after = t > run["estop"] + 0.1  # units at rest after the e-stop ramp: the model must know they stopped
    assert (err[after].max(axis=0) / amplitude).max() < 0.01
    ignoring = ForceEstimator(robot)  # the old mirror's failure: assumes the vibration went on
    ignoring.command_vibration(run["traj"], now=0.0)
    wrong = ignoring.estimate(t, struts, vib, strut_rates, vib_rates, eff)
    assert (np.abs(wrong.forces - eff)[after].max(axis=0) / amplitude).max() > 0.3
