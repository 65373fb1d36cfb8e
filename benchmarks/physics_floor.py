"""The physics floor: MuJoCo stepping the emulator's own model at 2 kHz with fixed controls, in C (one
``mujoco.rollout`` call, no Python per step, no ROS), against the emulator's core stepping the same model
(``HardwareEmulator.advance`` in 20 ms blocks, in-process, no ROS), per plant.

    python benchmarks/physics_floor.py [--seconds 20] [--plants ideal,realistic]

Prints per plant the steps per second of both, their ratio (the emulator core's share of MuJoCo's raw rate)
and the physics floor in cores (what stepping this model in real time costs at the least: 2,000 steps/s over
the raw rate). One JSON line per plant.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import mujoco
import numpy as np
from mujoco import rollout

from stewart_vibration import load_robot
from stewart_vibration.emulation.emulator import HardwareEmulator
from stewart_vibration.emulation.plant import load_plant
from stewart_vibration.install import default_config_dir
from stewart_vibration.sim.mjcf import load_simulation_settings

PHYSICS_HZ = 2000.0
BLOCK_S = 0.02  # the emulator node's pace period: one advance per burst of states


def emulator_for(plant_name: str) -> HardwareEmulator:
    robot = load_robot()
    plant = None if plant_name == "ideal" else load_plant(default_config_dir() / f"plant_{plant_name}.yaml", robot)
    return HardwareEmulator(robot, load_simulation_settings(timestep=1 / PHYSICS_HZ), plant=plant)


def core_rate(emu: HardwareEmulator, seconds: float) -> float:
    """Physics steps per wall second of the emulator's core holding the robot at rest."""
    emu.advance(0.2)  # settle, and plan the first blocks
    steps, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        steps += emu.advance(BLOCK_S)
    return steps / (time.perf_counter() - start)


def raw_rate(emu: HardwareEmulator, seconds: float) -> float:
    """Physics steps per wall second of MuJoCo alone on the emulator's model, from its state now, with its
    controls now held (one rollout call: C from the first step to the last)."""
    model = emu.sim.model
    data = mujoco.MjData(model)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, emu.sim.data, state, spec)
    steps = int(seconds * PHYSICS_HZ)
    control = np.tile(emu.sim.data.ctrl, (1, steps, 1))
    rollout.rollout(model, data, state[None], control[:, :100])  # warm up
    start = time.perf_counter()
    rollout.rollout(model, data, state[None], control)
    return steps / (time.perf_counter() - start)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=20.0, help="wall time of each measurement (s)")
    ap.add_argument("--plants", default="ideal,realistic")
    args = ap.parse_args()
    for name in args.plants.split(","):
        emu = emulator_for(name)
        core = core_rate(emu, args.seconds)
        raw = raw_rate(emu, args.seconds)
        print(json.dumps({"plant": name, "emulator_core_steps_per_s": round(core), "mujoco_raw_steps_per_s": round(raw),
                          "core_over_raw": round(core / raw, 3), "emulator_core_rtf": round(core / PHYSICS_HZ, 2),
                          "physics_floor_cores": round(PHYSICS_HZ / raw, 4)}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
