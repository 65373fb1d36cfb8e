"""What checking the 500 Hz streams costs: a burst of 10 states (the emulator's burst, what the kinematics node and
the estimator decode at once), 10 wrench estimates (kinematics' force-guard input) and 10 poses (the planning UI's
ground truth), each through what the nodes run now and through the unchecked decoding they ran before.

- states: ``decode_joint_states_dropping_malformed`` (with the nanosec check) + ``rows_within`` (finite, within
  10 m) against the same decoder's work + ``np.isfinite`` alone;
- wrenches / poses: ``messages.stamped`` (one numpy view per run of equal layout; frame, finiteness, unit
  quaternion checked per batch) against the former one-message-at-a-time decode.

Run: .venv/bin/python benchmarks/message_checks.py [--json]   (microseconds per burst of 10, best of 7)
"""

from __future__ import annotations

import argparse
import json
import timeit

import numpy as np

from stewart_vibration.kinematics.rotations import pose_from_position_quaternion
from stewart_vibration.messages.joint_states import (
    JointStateDecoder,
    JointStateEncoder,
    decode_joint_states,
    decode_joint_states_dropping_malformed,
)
from stewart_vibration.messages.stamped import MAX_JOINT_POSITION_M, poses_from_cdr, rows_within, wrenches_from_cdr
from stewart_vibration.messages.stamped_doubles import (
    PoseStampedEncoder,
    WrenchStampedEncoder,
    decode_pose_stamped,
    decode_wrench_stamped,
)
from stewart_vibration.robot import LEG_NAMES, VIB_NAMES

BURST = 10


def best_us(function, number: int = 2000) -> float:
    """Microseconds per call of ``function``: the best of 7 repeats of ``number`` calls."""
    return min(timeit.repeat(function, number=number, repeat=7)) / number * 1e6


def measure() -> dict:
    states = JointStateEncoder(LEG_NAMES + VIB_NAMES)
    burst = [states.encode(1 + 0.002 * i, np.full(12, 0.17), np.zeros(12), np.zeros(12)) for i in range(BURST)]
    decoder = JointStateDecoder()
    batch = decode_joint_states(burst, decoder)[0]
    lengths = batch.position[:, :6] + batch.position[:, 6:]
    wrench = WrenchStampedEncoder("base")
    wrenches = [wrench.encode(1 + 0.002 * i, np.zeros(6)) for i in range(BURST)]
    pose = PoseStampedEncoder("base")
    poses = [pose.encode(1 + 0.002 * i, [0.0, 0.0, 0.16], [0.0, 0.0, 0.0, 1.0]) for i in range(BURST)]

    def old_wrenches():
        decoded = [decode_wrench_stamped(m) for m in wrenches]
        return np.array([d[0] for d in decoded]), np.array([d[2] for d in decoded])

    def old_poses():
        decoded = [decode_pose_stamped(m) for m in poses]
        return pose_from_position_quaternion(np.array([d[2] for d in decoded]), np.array([d[3] for d in decoded]))

    return {
        "states_decode_us": best_us(lambda: decode_joint_states_dropping_malformed(burst, decoder)),
        "states_rows_within_us": best_us(lambda: rows_within(lengths, MAX_JOINT_POSITION_M)),
        "states_isfinite_only_us": best_us(lambda: np.isfinite(lengths).all(axis=1)),
        "wrenches_checked_us": best_us(lambda: wrenches_from_cdr(wrenches)),
        "wrenches_unchecked_before_us": best_us(old_wrenches),
        "poses_checked_us": best_us(lambda: poses_from_cdr(poses)),
        "poses_unchecked_before_us": best_us(old_poses),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true")
    results = measure()
    if parser.parse_args().json:
        print(json.dumps(results, indent=2))
    else:
        for key, value in results.items():
            print(f"{key:32s} {value:8.2f} us / burst of {BURST}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
