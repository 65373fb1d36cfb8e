"""Kinematic calibration on the realistic plant: the drawing's pose error, the calibrated one's, and whether
the identified parameters' covariance is honest, per plant seed, judged by the plant file's truth.

In process (emulation.calibration_bench: the emulated robot's sensors, no ROS), per seed: plan --poses
D-optimal calibration poses inside every limit (the condition number and the predicted parameter
uncertainty are printed before any pose is visited), set the robot at rest at each, average the tracker
(60 Hz, 20 um / 0.005 deg per frame) and the strut readings over --window s, identify the 42 parameters,
then over 20 validation poses of the reduction workspace (+-20 mm, +-15 deg, not used to identify) compare
forward kinematics of the strut readings against the true pose with the drawing and with the calibration.

Required (every seed): calibrated validation error <= 50 um and <= 0.01 deg (worst pose); goal <= 10 um
and <= 0.002 deg. Covariance: at least 99 % of all identified parameters within 3 standard deviations of
the truth, every one within 5.

Run: .venv/bin/python benchmarks/calibration.py [--seeds 10] [--poses 60] [--window 1.0] [--json]
Exit code 0 when every seed meets the required errors and the covariance is honest.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from stewart_vibration import load_robot
from stewart_vibration.calibration.geometry_parameters import parameters_of, robot_with_parameters
from stewart_vibration.calibration.identification import CalibrationData, identifiability, identify
from stewart_vibration.calibration.measurement_model import TrackerNoise
from stewart_vibration.calibration.pose_plan import plan_calibration_poses, reachable_candidates
from stewart_vibration.emulation.calibration_bench import measure_poses, pose_errors
from stewart_vibration.emulation.emulator import HardwareEmulator
from stewart_vibration.emulation.plant import load_plant
from stewart_vibration.install import default_config_dir
from stewart_vibration.kinematics.rotations import rotation_from_rpy
from stewart_vibration.sim.mjcf import load_simulation_settings

REQUIRED = {"position_um": 50.0, "angle_deg": 0.01}
GOAL = {"position_um": 10.0, "angle_deg": 0.002}
VALIDATION_POSES = 20


def one_seed(robot, seed: int, poses: int, window_s: float) -> dict:
    plant = load_plant(default_config_dir() / "plant_realistic.yaml", robot, seed=seed)
    s = plant.sensors
    noise = TrackerNoise(s.tracker_position_noise_m, np.radians(s.tracker_orientation_noise_deg))
    frames = int(round(window_s * s.tracker_rate_hz))
    plan = plan_calibration_poses(robot, poses, frames, noise)
    planned = CalibrationData(plan[:, :3], rotation_from_rpy(plan[:, 3:]), np.zeros((poses, 6)),
                              np.full(poses, float(frames)))
    condition, predicted = identifiability(parameters_of(robot), planned, noise)
    emu = HardwareEmulator(robot, load_simulation_settings(timestep=1 / 2000), plant=plant)
    started = time.perf_counter()
    calibration = measure_poses(emu, plan, window_s=window_s)
    result = identify(robot, calibration.data, noise)
    seconds = time.perf_counter() - started
    validation_poses = reachable_candidates(robot, VALIDATION_POSES, 0.02, np.radians(15),
                                            np.random.default_rng(1000 + seed))
    validation = measure_poses(emu, validation_poses, window_s=window_s)
    truth = np.concatenate([plant.robot.base_hinges.ravel(), plant.robot.platform_hinges.ravel(),
                            plant.strut_zero_offsets])
    z = np.abs(result.theta - truth) / result.std
    row = {"seed": seed, "poses": poses, "poses_used": int(result.used.sum()), "condition": condition,
           "predicted_std_max_um": 1e6 * float(predicted.max()), "std_max_um": 1e6 * float(result.std.max()),
           "reduced_chi2": result.reduced_chi2, "within_3_sigma": int((z <= 3).sum()), "within_5_sigma":
           int((z <= 5).sum()), "parameters": int(z.size), "z_max": float(z.max()), "seconds": seconds}
    for name, model in (("nominal", robot), ("calibrated", robot_with_parameters(robot, result.theta))):
        position, angle = pose_errors(model, validation.data.readings, validation.truth)
        row[f"{name}_position_um"] = 1e6 * float(position.max())
        row[f"{name}_angle_deg"] = float(np.degrees(angle.max()))
    return row


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--poses", type=int, default=60)
    parser.add_argument("--window", type=float, default=1.0, help="settle window per pose (s)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    robot = load_robot()
    rows = [one_seed(robot, seed, args.poses, args.window) for seed in range(1, args.seeds + 1)]
    errors_ok = all(r["calibrated_position_um"] <= REQUIRED["position_um"] and r["calibrated_angle_deg"] <=
                    REQUIRED["angle_deg"] for r in rows)
    goal_ok = all(r["calibrated_position_um"] <= GOAL["position_um"] and r["calibrated_angle_deg"] <=
                  GOAL["angle_deg"] for r in rows)
    total = sum(r["parameters"] for r in rows)
    within_3 = sum(r["within_3_sigma"] for r in rows) / total
    within_5 = sum(r["within_5_sigma"] for r in rows) == total
    honest = within_3 >= 0.99 and within_5
    if args.json:
        print(json.dumps({"rows": rows, "required_ok": errors_ok, "goal_ok": goal_ok, "within_3_sigma": within_3,
                          "all_within_5_sigma": within_5}, indent=1))
    else:
        print(f"{'seed':>4} {'cond':>6} {'pred std um':>11} {'used':>5} {'chi2/dof':>8} {'drawing um':>10} "
              f"{'drawing deg':>11} {'calib um':>9} {'calib deg':>9} {'|z| max':>7} {'fit s':>6}")
        for r in rows:
            print(f"{r['seed']:>4} {r['condition']:>6.0f} {r['predicted_std_max_um']:>11.1f} "
                  f"{r['poses_used']:>2}/{r['poses']:<2} {r['reduced_chi2']:>8.2f} "
                  f"{r['nominal_position_um']:>10.0f} {r['nominal_angle_deg']:>11.3f} "
                  f"{r['calibrated_position_um']:>9.2f} {r['calibrated_angle_deg']:>9.5f} "
                  f"{r['z_max']:>7.2f} {r['seconds']:>6.1f}")
        worst = max(rows, key=lambda r: r["calibrated_position_um"])
        print(f"worst calibrated validation error {worst['calibrated_position_um']:.2f} um, "
              f"{max(r['calibrated_angle_deg'] for r in rows):.5f} deg (required <= {REQUIRED['position_um']:g} um, "
              f"{REQUIRED['angle_deg']:g} deg: {'met' if errors_ok else 'MISSED'}; goal <= {GOAL['position_um']:g} um, "
              f"{GOAL['angle_deg']:g} deg: {'met' if goal_ok else 'missed'})")
        print(f"covariance: {100 * within_3:.1f} % of {total} parameters within 3 sigma of the truth, "
              f"{'all' if within_5 else 'NOT all'} within 5 ({'honest' if honest else 'NOT honest'})")
    return 0 if errors_ok and honest else 1


if __name__ == "__main__":
    sys.exit(main())
