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

import numpy as np

from .dynamics import leg_forces, leg_forces_paper
from .leg_kinematics import leg_motion
from .mjcf import SimulationSettings
from .mujoco_sim import StewartSim
from .paper import (
    CLINICAL_ACCELERATION_G,
    CLINICAL_FREQUENCY_HZ,
    PAPER_AMPLITUDE_M,
    PAPER_OMEGA_RAD_S,
    PAPER_PHASE_RAD,
    paper_pose,
)
from .robot import STANDARD_GRAVITY, Robot
from .rotations import rotation_from_rpy
from .tissue import TissueModel, tissue_wrench, wrench_about_point
from .trajectory import SinusoidalTrajectory, amplitude_for_acceleration, force_line_direction, vibration_trajectory


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
    mass), both (6,) base frame, of the tissue at the platform state in ``data`` (qpos, qvel)."""
    pose, twist = sim.platform_pose(data), sim.platform_twist(data)
    wrench = tissue_wrench(tissue, pose, twist)
    return wrench, wrench_about_point(wrench, rotation_from_rpy(pose[3:]) @ sim.robot.moving_body.com)


def simulate_trajectory(sim: StewartSim, trajectory: SinusoidalTrajectory, duration: float,
                        tissue: TissueModel | None = None) -> SimulationRun:
    """Drive the struts along the trajectory's leg lengths for ``duration`` s; record every step.
    ``tissue``: apply that soft-tissue load (evaluated at each step's start state) to the platform."""
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
    """Error measures of ``model`` forces against ``reference`` forces, both [n, 6]."""
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


def paper_scenario(robot: Robot) -> tuple[SinusoidalTrajectory, str]:
    """The paper's example: 1 um along the force line, sin(2 t + 2 pi / 3), at the paper pose."""
    pose = paper_pose(robot)
    traj = vibration_trajectory(pose, force_line_direction(pose).reshape(3), PAPER_AMPLITUDE_M,
                                PAPER_OMEGA_RAD_S / (2 * np.pi), PAPER_PHASE_RAD)
    return traj, "paper example: 1 um, 2 rad/s along the force line at the paper pose"


def clinical_scenario(robot: Robot) -> tuple[SinusoidalTrajectory, str]:
    """Clinical case: 35 Hz, 0.3 g peak along the force line at the paper pose."""
    pose = paper_pose(robot)
    amp = amplitude_for_acceleration(CLINICAL_ACCELERATION_G * STANDARD_GRAVITY, CLINICAL_FREQUENCY_HZ)
    traj = vibration_trajectory(pose, force_line_direction(pose).reshape(3), amp, CLINICAL_FREQUENCY_HZ)
    return traj, f"clinical: {CLINICAL_FREQUENCY_HZ:g} Hz, {CLINICAL_ACCELERATION_G:g} g ({amp * 1e6:.1f} um) " \
                 "along the force line at the paper pose"


def run_scenario(robot: Robot, name: str, duration: float, settings: SimulationSettings | None = None,
                 sim: StewartSim | None = None, tissue: TissueModel | None = None) -> ScenarioResult:
    """Simulate scenario ``name`` ("paper" or "clinical") for ``duration`` s and compare both models; with
    ``tissue`` the platform works against that soft-tissue load (both models get its wrench)."""
    traj, description = {"paper": paper_scenario, "clinical": clinical_scenario}[name](robot)
    if tissue is not None:
        description += f", against the tissue '{tissue.name}'"
    sim = sim or StewartSim(robot, settings)
    run = simulate_trajectory(sim, traj, duration, tissue)
    full = compare_forces(leg_forces(robot, run.pose, run.twist, run.accel, external_wrench=run.wrench), run.forces)
    paper = compare_forces(leg_forces_paper(robot, run.pose, run.twist, run.accel, external_wrench=run.wrench),
                           run.forces)
    tracking = float(np.abs(run.pose[:, :3] - run.reference_pose[:, :3]).max())
    return ScenarioResult(name, description, run, full, paper, tracking)
