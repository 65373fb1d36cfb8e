"""Newton-Euler vs MuJoCo: forward-simulate a prescribed platform motion and compare leg forces.

The six struts are driven (computed-force drive on the leg-length targets
from the analytic trajectory) so the platform follows the trajectory; the
forces MuJoCo applied are compared with ``leg_forces`` evaluated on the
platform motion MuJoCo actually produced (pose, twist, and the acceleration
of each recorded state re-evaluated with mj_forward), never on the
prescribed one. Scenarios: the paper's example and the clinical 35 Hz, 0.3 g
vibration along the force line at the paper's pose.

With a soft-tissue model (``tissue``), its wrench is evaluated from the simulated state at the start of
every step and applied over the step as MuJoCo's ``xfrc_applied`` on the platform (at the centre of
mass, world frame); the Newton-Euler side gets the same wrench as ``external_wrench``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import mujoco
import numpy as np

from ..kinematics.legs import leg_motion
from ..kinematics.rotations import rotation_from_rpy
from ..paper import (
    CLINICAL_ACCELERATION_G,
    CLINICAL_FREQUENCY_HZ,
    PAPER_AMPLITUDE_M,
    PAPER_OMEGA_RAD_S,
    PAPER_PHASE_RAD,
    paper_pose,
)
from ..robot import Robot
from ..sim.mjcf import SimulationSettings
from ..sim.mujoco_sim import StewartSim, universal_angles
from ..vibration.waveform import displacement_from_acceleration
from .newton_euler import leg_forces, leg_forces_paper
from .platform_trajectory import (
    SinusoidalTrajectory,
    force_line_direction,
    vibration_trajectory,
)
from .tissue import TissueModel, tissue_wrench, wrench_about_point


@dataclass(frozen=True)
class SimulationRun:
    """Recorded forward simulation, one row per step (state at the step start).

    time [n] (s); pose, twist, accel [n, 6] (simulated platform motion, base
    frame); forces [n, 6] (N, applied by MuJoCo, read from the force
    sensors); lengths [n, 6] (m); violation [n] (m, largest hinge gap);
    reference_pose [n, 6] (the prescribed trajectory).
    """

    time: np.ndarray
    pose: np.ndarray
    twist: np.ndarray
    accel: np.ndarray
    forces: np.ndarray
    lengths: np.ndarray
    violation: np.ndarray
    reference_pose: np.ndarray
    wrench: np.ndarray | None = None


def tissue_xfrc(sim: StewartSim, tissue: TissueModel, data=None) -> tuple[np.ndarray, np.ndarray]:
    """(wrench about the platform origin, the same as MuJoCo's xfrc_applied: moment about the centre of
    mass), both (6,) base frame, of the tissue at the platform state in ``data`` (qpos, qvel).

    Args:
        sim: the simulator.
        tissue: the tissue model.
        data: the MjData whose qpos, qvel give the platform state; None = ``sim.data``.

    Returns:
        (wrench, xfrc), both (6,) (N, N m; base frame): moment about the platform origin, and moment about
        the platform's centre of mass (for ``xfrc_applied``).
    """
    pose, twist = sim.platform_pose(data), sim.platform_twist(data)
    wrench = tissue_wrench(tissue, pose, twist)
    return wrench, wrench_about_point(wrench, rotation_from_rpy(pose[3:]) @ sim.robot.moving_body.com)


def simulate_trajectory(sim: StewartSim, trajectory: SinusoidalTrajectory, duration: float,
                        tissue: TissueModel | None = None) -> SimulationRun:
    """Drive the struts along the trajectory's leg lengths for ``duration`` s; record every step.

    The simulator is reset, set to the trajectory's state at t = 0 and stepped round(duration / timestep)
    times with the computed-force drive; each recorded row is the state at a step's start, re-evaluated
    with mj_forward.

    Args:
        sim: the simulator (its model's timestep sets the step); left at the final state.
        trajectory: the prescribed platform trajectory.
        duration: simulated time (s).
        tissue: optional soft-tissue load on the platform, evaluated at each step's start state.

    Returns:
        SimulationRun with n = round(duration / timestep) rows: time [n] (s), pose, twist, accel [n, 6],
        forces [n, 6] (N), lengths [n, 6] (m), violation [n] (m), reference_pose [n, 6] and wrench [n, 6]
        (the tissue's wrench about the platform origin, zeros without tissue).

    Raises:
        IndexError: ``duration`` rounds to zero steps.
    """
    dt = sim.model.opt.timestep
    steps = int(round(duration / dt))
    t = np.arange(steps) * dt
    ref = trajectory.sample(t)
    legs = leg_motion(sim.robot, ref.pose, ref.twist, ref.accel)
    sim.reset()
    sim.set_state(ref.pose[0], ref.twist[0])
    nq, nv = sim.model.nq, sim.model.nv
    qpos, qvel = np.empty((steps, nq)), np.empty((steps, nv))
    forces, wrench, xfrc = np.empty((steps, 6)), np.zeros((steps, 6)), np.zeros((steps, 6))
    platform = sim.model.body("platform").id
    for k in range(steps):
        if tissue is not None:
            wrench[k], xfrc[k] = tissue_xfrc(sim, tissue)
            sim.data.xfrc_applied[platform] = xfrc[k]
        f = sim.drive_forces(legs.length[k], legs.length_rate[k], legs.length_accel[k])
        qpos[k], qvel[k], forces[k] = sim.data.qpos, sim.data.qvel, f
        sim.step(f)
    pose, twist, accel = np.empty((steps, 6)), np.empty((steps, 6)), np.empty((steps, 6))
    lengths, violation, sensed = np.empty((steps, 6)), np.empty(steps), np.empty((steps, 6))
    for k in range(steps):
        sim._scratch.xfrc_applied[platform] = xfrc[k]
        pose[k], twist[k], accel[k], violation[k] = sim.evaluate(qpos[k], qvel[k], forces[k])
        lengths[k] = sim.leg_lengths(sim._scratch)
        sensed[k] = sim.actuator_forces(sim._scratch)
    return SimulationRun(t, pose, twist, accel, sensed, lengths, violation, ref.pose, wrench)


@dataclass(frozen=True)
class ForceComparison:
    """Model forces vs MuJoCo forces [n, 6] (N) and the error measures.

    rms_relative [6]: RMS(F_model - F_mujoco) / RMS(F_mujoco) per leg;
    overall: the same over all legs; worst: max of rms_relative;
    max_relative: max |F_model - F_mujoco| / max |F_mujoco|.
    """

    model: np.ndarray
    mujoco: np.ndarray
    rms_relative: np.ndarray
    overall: float
    worst: float
    max_relative: float


def compare_forces(model: np.ndarray, reference: np.ndarray) -> ForceComparison:
    """Error measures of ``model`` forces against ``reference`` forces, both [n, 6].

    Args:
        model: model forces [n, 6] (N).
        reference: reference (MuJoCo) forces [n, 6] (N).

    Returns:
        ForceComparison: per-leg RMS relative error [6], overall RMS relative error, the worst leg's, and
        max |model - reference| / max |reference|.
    """
    diff = model - reference
    per_leg = np.sqrt((diff**2).mean(axis=0)) / np.sqrt((reference**2).mean(axis=0))
    overall = float(np.sqrt((diff**2).mean()) / np.sqrt((reference**2).mean()))
    return ForceComparison(model, reference, per_leg, overall, float(per_leg.max()),
                           float(np.abs(diff).max() / np.abs(reference).max()))


@dataclass(frozen=True)
class ScenarioResult:
    """One validation scenario: its run, the full and the paper model comparisons."""

    name: str
    description: str
    run: SimulationRun
    full: ForceComparison
    paper: ForceComparison
    tracking_error: float  # max |pose - reference pose| over the position part, m
    amplitude: float  # the prescribed vibration's translation amplitude, m


def paper_scenario(robot: Robot) -> tuple[SinusoidalTrajectory, str]:
    """The paper's example: 1 um along the force line, sin(2 t + 2 pi / 3), at the paper pose.

    Args:
        robot: the robot.

    Returns:
        (trajectory, description): the SinusoidalTrajectory (1 um, 2 rad/s, phase 2 pi / 3, along the
        platform z axis at the paper pose) and a one-line description.
    """
    pose = paper_pose(robot)
    traj = vibration_trajectory(pose, force_line_direction(pose).reshape(3), PAPER_AMPLITUDE_M,
                                PAPER_OMEGA_RAD_S / (2 * np.pi), PAPER_PHASE_RAD)
    return traj, "paper example: 1 um, 2 rad/s along the force line at the paper pose"


def clinical_scenario(robot: Robot) -> tuple[SinusoidalTrajectory, str]:
    """Clinical case: 35 Hz, 0.3 g peak along the force line at the paper pose.

    Args:
        robot: the robot.

    Returns:
        (trajectory, description): the SinusoidalTrajectory (amplitude 0.3 g / (2 pi 35 Hz)^2 in m, phase 0,
        along the platform z axis at the paper pose) and a one-line description.
    """
    pose = paper_pose(robot)
    amp = displacement_from_acceleration(CLINICAL_ACCELERATION_G, CLINICAL_FREQUENCY_HZ)
    traj = vibration_trajectory(pose, force_line_direction(pose).reshape(3), amp, CLINICAL_FREQUENCY_HZ)
    return traj, f"clinical: {CLINICAL_FREQUENCY_HZ:g} Hz, {CLINICAL_ACCELERATION_G:g} g ({amp * 1e6:.1f} um) " \
                 "along the force line at the paper pose"


def run_scenario(robot: Robot, name: str, duration: float, settings: SimulationSettings | None = None,
                 sim: StewartSim | None = None, tissue: TissueModel | None = None) -> ScenarioResult:
    """Simulate scenario ``name`` ("paper" or "clinical") for ``duration`` s and compare both models.

    With ``tissue`` the platform works against that soft-tissue load (both models get its wrench).

    Args:
        robot: the robot.
        name: "paper" or "clinical".
        duration: simulated time (s).
        settings: simulation settings for a new StewartSim (ignored when ``sim`` is given).
        sim: an existing simulator to use (reset by the run).
        tissue: optional soft-tissue load.

    Returns:
        ScenarioResult: the run, the full and the paper model's force comparisons against MuJoCo, the
        tracking error (max position error, m) and the vibration's translation amplitude (m).

    Raises:
        KeyError: ``name`` is neither "paper" nor "clinical".
        IndexError: ``duration`` rounds to zero steps (``simulate_trajectory``).
    """
    traj, description = {"paper": paper_scenario, "clinical": clinical_scenario}[name](robot)
    if tissue is not None:
        description += f", against the tissue '{tissue.name}'"
    sim = sim or StewartSim(robot, settings)
    run = simulate_trajectory(sim, traj, duration, tissue)
    full = compare_forces(leg_forces(robot, run.pose, run.twist, run.accel, external_wrench=run.wrench), run.forces)
    paper = compare_forces(leg_forces_paper(robot, run.pose, run.twist, run.accel, external_wrench=run.wrench),
                           run.forces)
    tracking = float(np.abs(run.pose[:, :3] - run.reference_pose[:, :3]).max())
    amplitude = float(np.linalg.norm(traj.amplitude[:, :3], axis=1).sum())
    return ScenarioResult(name, description, run, full, paper, tracking, amplitude)


# -- exact checks of the Newton-Euler model against MuJoCo's equations (docs/dynamics.md) -----------------


def closed_chain_forces(sim: StewartSim, qacc: np.ndarray, data=None):
    """Solve MuJoCo's equations of motion for the actuator forces at the current state.

    [B  J_c^T] [F; lambda] = M qacc + c, with M from mj_fullM, c = qfrc_bias - qfrc_passive
    (Coriolis, centrifugal, gravity, minus passive forces), J_c the equality (connect) constraint Jacobian
    rows and B the actuator map, solved by least squares. Requires mj_forward at the state (set_state does it).

    Args:
        sim: the simulator.
        qacc: generalised accelerations (nv,) (e.g. from ``StewartSim.set_state``).
        data: the MjData of the state; None = ``sim.data``.

    Returns:
        (F, lambda, residual): actuator forces F (nu,) = (6,) (N), constraint forces lambda (one per equality
        constraint row), and the relative residual |A x - b| / |b| of the least-squares solve.
    """
    m, d = sim.model, (sim.data if data is None else data)
    mass = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, mass)
    rows = np.flatnonzero(d.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY)
    jac = d.efc_J.reshape(-1, m.nv)[rows] if d.efc_J.size else np.zeros((0, m.nv))
    rhs = mass @ qacc + d.qfrc_bias - d.qfrc_passive
    lhs = np.hstack([sim.actuator_map, jac.T])
    sol, *_ = np.linalg.lstsq(lhs, rhs, rcond=None)
    residual = np.linalg.norm(lhs @ sol - rhs) / max(cast(float, np.linalg.norm(rhs)), 1e-300)
    return sol[:m.nu], sol[m.nu:], residual


def universal_spin(sim: StewartSim, pose, twist, accel):
    """Leg spin rate and spin acceleration (6,) each (rad/s, rad/s^2) a universal joint imposes.

    The Newton-Euler model assumes zero spin about the leg axis; the U-joint
    forces spin = w_cyl . s with w_cyl = x q1' + (Rx(q1) y) q2' (home leg frame).

    Args:
        sim: the simulator (its home leg frames).
        pose: platform pose (6,) (m, rad).
        twist: platform twist (6,) = [v, w] (m/s, rad/s; base frame).
        accel: platform acceleration (6,) = [a, alpha] (m/s^2, rad/s^2; base frame).

    Returns:
        (spin, spin_acc, motion): spin rates (6,) (rad/s), spin accelerations (6,) (rad/s^2) and the
        LegMotion of the state.

    Raises:
        InvalidInputError: pose, twist or accel is not numeric, not [..., 6] or not finite (``leg_motion``).
    """
    lm = leg_motion(sim.robot, pose, twist, accel)
    spin, spin_acc = np.zeros(6), np.zeros(6)
    for i in range(6):
        f0 = sim.leg_frames[i]
        s, sd, sdd = f0.T @ lm.axis[i], f0.T @ lm.axis_rate[i], f0.T @ lm.axis_accel[i]
        q, qd, qdd = universal_angles(s, sd, sdd)
        u1 = np.array([1.0, 0.0, 0.0])
        u2 = np.array([0.0, np.cos(q[0]), np.sin(q[0])])
        u2_dot = np.cross(u1 * qd[0], u2)
        w = u1 * qd[0] + u2 * qd[1]
        w_dot = u1 * qdd[0] + u2 * qdd[1] + u2_dot * qd[1]
        spin[i] = w @ s
        spin_acc[i] = w_dot @ s + w @ sd
    return spin, spin_acc, lm


def leg_spin_force_correction(sim: StewartSim, pose, twist, accel) -> np.ndarray:
    """Axial-force change (6,) (N) caused by the U-joint leg spin the Newton-Euler model ignores.

    The spin adds d/dt(I_a w_s s) = I_a (w_s' s + w_s s') to each leg's moment
    about B_i (I_a = cylinder + piston axial inertia). Its component along the
    leg is taken by the U-joint torque tau n (n = u1 x u2, so
    tau = dM.s / n.s); the rest, dM - tau n, is balanced by an extra transverse
    force at A_i, dh = s x (dM - tau n) / l, which the six struts carry:
    H dF = -sum [dh; rho x dh]. This is the documented bound of the exact
    static check with universal joints (first order in I_a, exact at a
    consistent state).

    Args:
        sim: the simulator (robot and home leg frames).
        pose: platform pose (6,) (m, rad).
        twist: platform twist (6,) = [v, w] (m/s, rad/s; base frame).
        accel: platform acceleration (6,) = [a, alpha] (m/s^2, rad/s^2; base frame).

    Returns:
        dF (6,) (N), to add to the Newton-Euler axial forces.

    Raises:
        InvalidInputError: pose, twist or accel is not numeric, not [..., 6] or not finite (``leg_motion``).
        numpy.linalg.LinAlgError: H is singular.
    """
    spin, spin_acc, lm = universal_spin(sim, pose, twist, accel)
    p = sim.robot.leg_bodies
    ia = p.cylinder_inertia_axial + p.piston_inertia_axial
    rot = lm.rotation
    c = rot @ sim.robot.moving_body.com
    wrench = np.zeros(6)
    cols = np.zeros((6, 6))
    for i in range(6):
        s = lm.axis[i]
        d_m = ia * (spin_acc[i] * s + spin[i] * lm.axis_rate[i])
        f0 = sim.leg_frames[i]
        q, _, _ = universal_angles(f0.T @ s, f0.T @ lm.axis_rate[i], f0.T @ lm.axis_accel[i])
        n = f0 @ np.cross([1.0, 0.0, 0.0], [0.0, np.cos(q[0]), np.sin(q[0])])
        tau = (d_m @ s) / (n @ s)
        dh = np.cross(s, d_m - tau * n) / lm.length[i]
        rho = lm.arm[i] - c
        wrench -= np.r_[dh, np.cross(rho, dh)]
        cols[:, i] = np.r_[s, np.cross(rho, s)]
    return np.linalg.solve(cols, wrench)
