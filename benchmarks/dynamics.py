"""Benchmark: leg_forces samples/s (batched) and MuJoCo steps/s at the validation settings.

Run: .venv/bin/python benchmarks/dynamics.py [--samples N]
Target: leg_forces >= 1 M samples/s batched.
"""

from __future__ import annotations

import argparse
import os
import time

import mujoco
import numpy as np

from stewart_vibration import load_robot
from stewart_vibration.dynamics.mujoco_validation import clinical_scenario
from stewart_vibration.dynamics.newton_euler import leg_forces, leg_forces_paper
from stewart_vibration.kinematics.legs import leg_motion
from stewart_vibration.paper import paper_pose
from stewart_vibration.sim.mjcf import load_simulation_settings
from stewart_vibration.sim.mujoco_sim import StewartSim


def best_rate(func, count: int, repeats: int = 3, clock=time.perf_counter) -> float:
    """Best of ``repeats`` rates (count / elapsed) measured with ``clock``."""
    best = 0.0
    for _ in range(repeats):
        start = clock()
        func()
        best = max(best, count / (clock() - start))
    return best


def report(label: str, func, count: int, unit: str = "samples/s") -> None:
    """Wall-clock rate and CPU-time rate (the latter is what an unshared core would give)."""
    wall = best_rate(func, count)
    cpu = best_rate(func, count, clock=time.process_time)
    print(f"{label:23s}: {wall:12,.0f} {unit} wall-clock, {cpu:12,.0f} per CPU-second")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=400_000)
    parser.add_argument("--steps", type=int, default=20_000)
    args = parser.parse_args()
    robot = load_robot()
    rng = np.random.default_rng(0)
    n = args.samples
    pose = paper_pose(robot) + rng.uniform(-1, 1, (n, 6)) * [0.01, 0.01, 0.01, 0.1, 0.1, 0.1]
    twist, accel = rng.normal(size=(n, 6)), rng.normal(size=(n, 6))
    report("leg_forces (full)", lambda: leg_forces(robot, pose, twist, accel), n)
    report("leg_forces_paper", lambda: leg_forces_paper(robot, pose, twist, accel), n)

    def single():
        for _ in range(2000):
            leg_forces(robot, pose[0], twist[0], accel[0])

    report("leg_forces, 1 sample", single, 2000, "calls/s")
    report("leg_motion", lambda: leg_motion(robot, pose, twist, accel), n)
    print(f"(load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores: wall-clock rates drop when shared)")

    settings = load_simulation_settings()
    dt = settings.timestep
    sim = StewartSim(robot, settings)
    m, d = sim.model, sim.data
    sim.reset(paper_pose(robot))
    d.ctrl[:] = leg_forces(robot, paper_pose(robot), np.zeros(6), np.zeros(6))
    steps = args.steps

    def raw():
        for _ in range(steps):
            mujoco.mj_step(m, d)

    rate = best_rate(raw, steps)
    print(f"MuJoCo mj_step ({settings.integrator}, dt {dt:g} s): {rate:10,.0f} steps/s, "
          f"real-time factor {rate * dt:.2f}")
    traj, _ = clinical_scenario(robot)
    ref = traj.sample(np.arange(2000) * dt)
    legs = leg_motion(robot, ref.pose, ref.twist, ref.accel)
    for interval in (1, 20):
        sim = StewartSim(robot, settings, gain_interval=interval)
        sim.reset()
        sim.set_state(ref.pose[0], ref.twist[0])

        def driven(sim=sim):
            for k in range(2000):
                sim.step_tracking(legs.length[k], legs.length_rate[k], legs.length_accel[k])

        rate = best_rate(driven, 2000, repeats=1)
        print(f"computed-force drive, gain every {interval:2d} steps (python loop): {rate:8,.0f} steps/s, "
              f"real-time factor {rate * dt:.2f}")

if __name__ == "__main__":
    main()
