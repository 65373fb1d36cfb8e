"""Generated MuJoCo model and the exact static check against MuJoCo's own equations."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest

from stewart_vibration.dynamics.mujoco_validation import closed_chain_forces, leg_spin_force_correction
from stewart_vibration.dynamics.newton_euler import leg_forces, leg_forces_paper
from stewart_vibration.paper import paper_pose
from stewart_vibration.sim.mjcf import build_mjcf, load_simulation_settings
from stewart_vibration.sim.mujoco_sim import StewartSim


@pytest.fixture(scope="module")
def sims(robot):
    return {bj: StewartSim(robot, base_joint=bj) for bj in ("ball", "universal")}


def random_states(robot, count=4, seed=0):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        pose = paper_pose(robot) + rng.uniform(-1, 1, 6) * np.array([0.01, 0.01, 0.01, 0.1, 0.1, 0.1])
        twist = rng.normal(size=6) * np.array([0.05, 0.05, 0.05, 0.5, 0.5, 0.5])
        accel = rng.normal(size=6) * np.array([3.0, 3.0, 3.0, 30.0, 30.0, 30.0])
        yield pose, twist, accel


def test_model_matches_config(robot, sims):
    m = sims["universal"].model
    leg = robot.leg
    assert m.nu == 6 and m.neq == 6 and m.nsensor == 6
    assert m.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    settings = load_simulation_settings()
    assert m.opt.timestep == settings.timestep
    assert np.allclose(m.eq_solref, [2 * settings.timestep, 1.0])
    for i in range(1, 7):
        assert m.body(f"cylinder_{i}").mass[0] == pytest.approx(leg.cylinder_mass)
        assert m.body(f"piston_{i}").mass[0] == pytest.approx(leg.piston_mass + leg.vibration_unit_mass)
    assert m.body("platform").mass[0] == pytest.approx(robot.platform.mass + robot.payload.mass)
    assert np.allclose(m.body("platform").ipos, robot.moving_body.com)
    assert not np.any(m.dof_armature)
    assert "<connect" in build_mjcf(robot) and "ball" in build_mjcf(robot, base_joint="ball")


def test_assembled_at_home(robot, sims):
    for sim in sims.values():
        d = mujoco.MjData(sim.model)
        mujoco.mj_forward(sim.model, d)
        assert sim.constraint_violation(d) < 1e-15
        assert np.allclose(sim.platform_pose(d), robot.home_pose, atol=1e-15)
        from stewart_vibration.kinematics import inverse_kinematics

        assert np.allclose(sim.leg_lengths(d), inverse_kinematics(robot, robot.home_pose), atol=1e-15)


@pytest.mark.parametrize("base_joint", ["ball", "universal"])
def test_set_state_is_consistent(robot, sims, base_joint):
    sim = sims[base_joint]
    for pose, twist, _ in random_states(robot, 2, seed=1):
        sim.set_state(pose, twist)
        assert sim.constraint_violation() < 1e-14
        rows = sim.data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY
        assert np.abs(sim.data.efc_vel[rows]).max() < 1e-14  # J_c qvel = 0
        assert np.allclose(sim.platform_pose(), pose, atol=1e-14)
        assert np.allclose(sim.platform_twist(), twist, atol=1e-14)


def test_exact_static_check_ball_joints(robot, sims):
    """[B J_c^T][F; lambda] = M qacc + c agrees with leg_forces to <= 1e-9 relative."""
    sim = sims["ball"]
    for pose, twist, accel in random_states(robot, 4):
        qacc = sim.set_state(pose, twist, accel)
        forces, _, residual = closed_chain_forces(sim, qacc)
        expected = leg_forces(robot, pose, twist, accel)
        assert residual < 1e-12  # the state is consistent: the system is solvable exactly
        assert np.abs(forces - expected).max() <= 1e-9 * np.abs(expected).max()
        # the check can fail: the paper model is far off
        paper = leg_forces_paper(robot, pose, twist, accel)
        assert np.abs(forces - paper).max() > 1e-3 * np.abs(expected).max()


def test_exact_static_check_universal_joints_within_spin_bound(robot, sims):
    """With U-joints the only difference is the leg spin the U-joint imposes (documented bound)."""
    sim = sims["universal"]
    for pose, twist, accel in random_states(robot, 4, seed=2):
        qacc = sim.set_state(pose, twist, accel)
        forces, _, residual = closed_chain_forces(sim, qacc)
        expected = leg_forces(robot, pose, twist, accel)
        spin = leg_spin_force_correction(sim, pose, twist, accel)
        scale = np.abs(expected).max()
        assert residual < 1e-12
        assert np.abs(forces - expected).max() <= np.abs(spin).max() + 1e-9 * scale
        assert np.abs(forces - (expected + spin)).max() <= 1e-9 * scale
        assert np.abs(spin).max() <= 1e-5 * scale  # the bound is small at these rates


def test_static_equilibrium_holds_under_newton_euler_forces(robot):
    """Static forces from leg_forces hold the simulated robot still (gravity only)."""
    sim = StewartSim(robot)
    pose = paper_pose(robot)
    sim.reset(pose)
    forces = leg_forces(robot, pose, np.zeros(6), np.zeros(6))
    for _ in range(200):
        sim.step(forces)
    assert np.abs(sim.platform_pose() - pose).max() < 1e-9
    assert np.allclose(sim.actuator_forces(), forces)


@pytest.mark.parametrize("gravity", [[0.0, -9.81, 0.0], [4.0, -5.0, -7.0]])
def test_static_forces_hold_the_robot_under_tilted_gravity(robot, gravity):
    """A leg on its side (gravity across the base frame, e.g. a patient lying laterally): the static forces
    from leg_forces, with the gravity of robot.yaml replaced, hold MuJoCo's robot still."""
    tilted = dataclasses.replace(robot, gravity=np.array(gravity))
    sim = StewartSim(tilted)
    pose = paper_pose(tilted)
    sim.reset(pose)
    forces = leg_forces(tilted, pose, np.zeros(6), np.zeros(6))
    assert np.abs(forces - leg_forces(robot, pose, np.zeros(6), np.zeros(6))).max() > 1.0  # gravity matters
    for _ in range(200):
        sim.step(forces)
    assert np.abs(sim.platform_pose() - pose).max() < 1e-9
