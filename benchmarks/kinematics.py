"""Kinematics speed: IK throughput, loop ratio, batched FK, warm single-solve latency.

Run: tools/bench kinematics   (or: .venv/bin/python benchmarks/kinematics.py)
Prints measured numbers, the issue's targets and the ratio to each target.
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

from stewart_vibration import forward_kinematics, inverse_kinematics, load_robot
from stewart_vibration.parallel import worker_count


def workspace_poses(robot, count, seed=0):
    rng = np.random.default_rng(seed)
    offsets = np.concatenate(
        [rng.uniform(-0.02, 0.02, (count, 3)), rng.uniform(-np.radians(15), np.radians(15), (count, 3))], axis=1
    )
    return robot.home_pose + offsets


def best_of(fn, repeats):
    """Smallest wall time of ``repeats`` calls (s): the least disturbed run."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--ik-batch", type=int, default=1_000_000)
    parser.add_argument("--fk-batch", type=int, default=100_000)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    robot = load_robot()
    poses = workspace_poses(robot, args.ik_batch)

    ik_checked = args.ik_batch / best_of(lambda: inverse_kinematics(robot, poses), 3)
    ik_unchecked = args.ik_batch / best_of(lambda: inverse_kinematics(robot, poses, check_limits=False), 3)
    loop_n = 20_000
    loop_time = best_of(lambda: [inverse_kinematics(robot, q) for q in poses[:loop_n]], 1)
    ik_loop = loop_n / loop_time
    threads = worker_count()
    saved = os.environ.get("STEWART_VIBRATION_THREADS")
    os.environ["STEWART_VIBRATION_THREADS"] = "1"
    ik_one_thread = args.ik_batch / best_of(lambda: inverse_kinematics(robot, poses), 3)
    if saved is None:
        del os.environ["STEWART_VIBRATION_THREADS"]
    else:
        os.environ["STEWART_VIBRATION_THREADS"] = saved

    fk_poses = poses[: args.fk_batch]
    lengths = inverse_kinematics(robot, fk_poses)
    fk_cold = args.fk_batch / best_of(lambda: forward_kinematics(robot, lengths), 2)
    guess = fk_poses + np.concatenate([np.full(3, 1e-5), np.full(3, 1e-4)]) / np.sqrt(3)
    fk_warm = args.fk_batch / best_of(lambda: forward_kinematics(robot, lengths, guess=guess), 2)

    single_lengths, single_guess = lengths[0], guess[0]
    for _ in range(200):
        forward_kinematics(robot, single_lengths, guess=single_guess)
    samples = []
    for _ in range(3000):
        start = time.perf_counter()
        forward_kinematics(robot, single_lengths, guess=single_guess)
        samples.append(time.perf_counter() - start)
    samples = np.array(samples) * 1e6

    results = {
        "ik_poses_per_s_checked": ik_checked,
        "ik_poses_per_s_unchecked": ik_unchecked,
        "ik_poses_per_s_python_loop": ik_loop,
        "ik_poses_per_s_checked_one_thread": ik_one_thread,
        "batch_threads": threads,
        "ik_ratio_vs_loop": ik_checked / ik_loop,
        "fk_solves_per_s_batched_cold": fk_cold,
        "fk_solves_per_s_batched_warm": fk_warm,
        "fk_warm_single_latency_us_p50": float(np.median(samples)),
        "fk_warm_single_latency_us_p99": float(np.percentile(samples, 99)),
    }
    targets = [
        ("IK poses/s (1e6 batch, limits checked)", ik_checked, 10e6, "higher"),
        ("IK poses/s (1e6 batch, no limit checks)", ik_unchecked, 10e6, "higher"),
        ("IK batched / per-pose Python loop", ik_checked / ik_loop, 100.0, "higher"),
        ("FK solves/s batched, cold start", fk_cold, 200e3, "higher"),
        ("FK solves/s batched, warm start", fk_warm, 200e3, "higher"),
        ("FK warm single solve p50 (us)", results["fk_warm_single_latency_us_p50"], 100.0, "lower"),
    ]
    if args.json:
        print(json.dumps(results, indent=2))
        return 0
    print(f"{'measure':44s} {'value':>14s} {'target':>12s} {'ratio':>8s}")
    for name, value, target, better in targets:
        ratio = value / target if better == "higher" else target / value
        print(f"{name:44s} {value:14.4g} {target:12.4g} {ratio:8.2f}{'' if ratio >= 1 else '  (below target)'}")
    print(f"{'FK warm single solve p99 (us)':44s} {results['fk_warm_single_latency_us_p99']:14.4g}")
    print(f"{'IK per-pose Python loop (poses/s)':44s} {ik_loop:14.4g}")
    print(f"{'IK poses/s checked, one thread':44s} {ik_one_thread:14.4g}")
    print(f"batches split over {threads} thread(s) (STEWART_VIBRATION_THREADS; 1 = off)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
