"""Physics that can never publish nonsense (emulation.physics_guard): a divergence -- an absurd force, a
corrupted state, the platform driven through a singularity -- latches a fault, the robot is held at its last
good state (finite, at rest), every command is refused with the typed fault, and sim time never goes back;
MuJoCo's own reset-on-instability (time back to 0) is switched off."""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np
import pytest
from rclpy.serialization import serialize_message

from stewart_vibration import inverse_kinematics
from stewart_vibration.dynamics.tissue_config import load_tissue
from stewart_vibration.emulation.emulator import HardwareEmulator
from stewart_vibration.emulation.strut_trajectory import build_trajectory, checked_command
from stewart_vibration.errors import PhysicsFaultError
from stewart_vibration.install import default_config_dir
from stewart_vibration.messages.status_values import vibration_report_from_cdr
from stewart_vibration.motion.profiles import minimum_jerk, minimum_jerk_duration
from stewart_vibration.nodes.status_messages import vibration_status_msg
from stewart_vibration.robot import LEG_NAMES, VIB_NAMES
from stewart_vibration.sim.mjcf import load_simulation_settings
from stewart_vibration.sim.mujoco_sim import StewartSim

PERIOD = 0.002
SETTINGS = dict(timestep=1 / 2000)


@pytest.fixture(autouse=True)
def in_tmp_path(tmp_path, monkeypatch):
    """MuJoCo appends its warnings to MUJOCO_LOG.TXT in the working directory: keep it out of the repository."""
    monkeypatch.chdir(tmp_path)


def published(emu):
    """What the node publishes from the emulator after a block: (time, joint positions, velocities, efforts,
    platform pose)."""
    _, pos, vel, eff = emu.joint_state()
    return emu.time, pos, vel, eff, emu.platform_pose()


def run(emu, until):
    rows = []
    while emu.time < until - 1e-12:
        emu.advance(PERIOD)
        rows.append(published(emu))
    return rows


def assert_held(robot, rows, held_pose):
    """Every row finite, time strictly increasing, the robot at rest at ``held_pose`` and inside the stroke."""
    times = np.array([r[0] for r in rows])
    assert (np.diff(times) > 0).all()
    for _, pos, vel, eff, pose in rows:
        assert np.isfinite(pos).all() and np.isfinite(vel).all() and np.isfinite(eff).all() and np.isfinite(pose).all()
        assert np.abs(vel).max() == 0.0
        assert np.abs(pose - held_pose).max() == 0.0
        assert robot.limits.stroke_min <= pos[:6].min() and pos[:6].max() <= robot.limits.stroke_max


def assert_fault_reported(emu, words):
    report = emu.vibration_report()[0]
    assert report.state == "estopped" and report.level == "error" and words in report.fault
    wire = vibration_report_from_cdr(serialize_message(vibration_status_msg(report)))  # what subscribers read
    assert wire.fault == report.fault and wire.state == "estopped" and wire.level == "error"
    with pytest.raises(PhysicsFaultError) as refused:
        emu.command_struts(LEG_NAMES, 0.0, [1.0], [emu.home_lengths])
    assert refused.value.reason == emu.fault.reason and refused.value.time == emu.fault.time
    with pytest.raises(PhysicsFaultError):
        emu.command_vibration(VIB_NAMES, 0.0, [0.1], [np.zeros(6)])
    with pytest.raises(PhysicsFaultError):
        emu.reset()


def test_an_absurd_force_latches_a_fault_and_the_robot_is_held(robot):
    emu = HardwareEmulator(robot, load_simulation_settings(**SETTINGS))
    run(emu, 0.2)
    good = emu.platform_pose()
    emu.sim.data.xfrc_applied[emu.sim.model.body("platform").id] = [0.0, 0.0, 1e7, 0.0, 0.0, 0.0]  # 10 MN
    emu.advance(PERIOD)
    assert emu.fault is not None and abs(emu.fault.time - emu.time) < 1e-9
    assert "following error" in emu.fault.reason or "joint" in emu.fault.reason
    held = emu.platform_pose()
    assert np.abs(held - good).max() < 1e-6  # the last good state: the block before the force
    rows = run(emu, 0.6)
    assert_held(robot, rows, held)
    assert_fault_reported(emu, emu.fault.reason)


def test_a_corrupted_state_latches_a_fault(robot):
    emu = HardwareEmulator(robot, load_simulation_settings(**SETTINGS))
    run(emu, 0.1)
    good = emu.platform_pose()
    emu.sim.data.qvel[3] = np.nan
    rows = run(emu, 0.3)
    assert emu.fault is not None and "non-finite" in emu.fault.reason
    assert_held(robot, rows, good)
    assert_fault_reported(emu, "non-finite")


def test_mujoco_resets_time_on_a_bad_acceleration_unless_told_not_to(robot):
    """MuJoCo's mj_checkVel / mj_checkAcc answer a huge value by mj_resetData: time back to 0 -- the 19 s jump
    back seen on /clock. The emulator's model has mjDSBL_AUTORESET set: time goes on, the fault latches."""
    sim = StewartSim(robot, load_simulation_settings(integrator="Euler", **SETTINGS))
    for _ in range(200):
        mujoco.mj_step(sim.model, sim.data)
    sim.data.qvel[:] = 1e30
    mujoco.mj_step(sim.model, sim.data)
    assert sim.data.time < 0.01  # reset: the reference behaviour

    emu = HardwareEmulator(robot, load_simulation_settings(**SETTINGS))
    run(emu, 0.1)
    before = emu.time
    emu.sim.data.qvel[:] = 1e30
    rows = run(emu, 0.3)
    assert emu.time > before and all(r[0] > before for r in rows)
    assert emu.fault is not None
    assert_fault_reported(emu, "")


def test_a_trajectory_through_a_singularity_forced_past_the_acceptance_is_held_not_published(robot):
    """The +45/-30/+45/-30/+45/-30 mm command (legal per strut), pushed into the follower with the per-strut
    checks only (what the emulator accepted before): the platform is driven through a singularity and MuJoCo
    goes unstable; the guard latches there, so no published strut length leaves the stroke (they reached
    16-87 m), nothing is non-finite and time never goes back (it jumped back 19 s)."""
    emu = HardwareEmulator(robot, load_simulation_settings(**SETTINGS))
    home = emu.home_lengths
    goal = home + np.array([0.045, -0.03] * 3)
    duration = minimum_jerk_duration(home, goal, 0.9 * robot.limits.strut_velocity_max, 0.5)
    times = np.linspace(duration / 100, duration, 100)
    traj = build_trajectory(LEG_NAMES, LEG_NAMES, 0.0, times, *minimum_jerk(home, goal, duration, times))
    emu.struts.replace(checked_command(emu.struts, traj, 0.0, robot.limits), 0.0)
    emu._changed()
    rows = run(emu, duration + 1.0)
    assert emu.fault is not None, "the forced command did not diverge: the test no longer shows the guard"
    times = np.array([r[0] for r in rows])
    assert (np.diff(times) > 0).all() and times[-1] >= duration + 1.0 - 1e-9
    lengths = np.array([r[1][:6] for r in rows])
    assert np.isfinite(lengths).all()
    assert lengths.min() >= robot.limits.stroke_min - 1e-3 and lengths.max() <= robot.limits.stroke_max + 1e-3
    speeds = np.array([r[2][:6] for r in rows])
    assert np.abs(speeds).max() < 1.0  # they reached 9.6-7,928 m/s


def test_an_exception_inside_a_block_latches_a_fault(robot, tmp_path):
    """A tissue stiffening e-fold every 1 um (length_m 1e-6): its wrench runs to infinity (MN within a fraction
    of a millimetre, then an OverflowError: it killed the physics thread) -- a fault latches, the robot is held
    and the states stay finite."""
    # the tissue file check refuses such a length; the physics must survive it anyway (a model built in code)
    tissue = replace(load_tissue(default_config_dir() / "tissue.yaml", robot), length_m=1e-6)
    emu = HardwareEmulator(robot, load_simulation_settings(**SETTINGS), tissue=tissue)
    goal = inverse_kinematics(robot, robot.home_pose + np.array([0, 0, 0.002, 0, 0, 0]))
    times = np.linspace(0.05, 2.0, 40)
    emu.command_struts(LEG_NAMES, 0.0, times, *minimum_jerk(emu.home_lengths, goal, 2.0, times))
    rows = run(emu, 2.5)
    assert emu.fault is not None and any(w in emu.fault.reason for w in ("OverflowError", "non-finite", "warning"))
    assert all(np.isfinite(r[1]).all() and np.isfinite(r[4]).all() for r in rows)
    assert (np.diff([r[0] for r in rows]) > 0).all()
