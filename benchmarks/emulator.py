"""Hardware emulator speed: real-time factor, achieved state rate, command-to-state latency.

Starts the hardware_emulator node as its own process (real DDS, own ROS domain)
and measures from a client process:
- max real-time factor (real_time_factor 0 = as fast as possible) at the suite's settings,
- achieved legs/joint_states rate (Hz of wall time) at real_time_factor 1,
- command-to-state latency: wall time from publishing a leg trajectory (stamp 0 = now,
  first point 2 ms later, +-2 um) to the first joint state that shows the move (p50, p99).

Run: .venv/bin/python benchmarks/emulator.py [--seconds 8] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test"))

from ros_client import RosTestClient  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint  # noqa: E402

from stewart_vibration import inverse_kinematics, load_robot  # noqa: E402
from stewart_vibration.install import default_config_dir  # noqa: E402
from stewart_vibration.nodes.message_conversions import duration_msg  # noqa: E402
from stewart_vibration.runtime.processes import claim_ros_domain, ros_environment, start_python_module  # noqa: E402

LEGS = [f"leg_{i}" for i in range(1, 7)]


def start_emulator(domain: int, rtf: float, log_dir: Path, plant: str = "ideal"):
    """The hardware_emulator node at the suite's settings, ``rtf`` and ``plant`` (ideal, realistic or a file)."""
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    args = ["--ros-args", "--params-file", str(default_config_dir() / "suite_params.yaml"),
            "-p", f"real_time_factor:={rtf}", "-p", f"plant_config:={plant}"]
    return start_python_module("emulator", "stewart_vibration.nodes.hardware_emulator_node", args,
                               ros_environment(domain), log_dir)


def measure_rtf_and_rate(domain: int, rtf: float, seconds: float, log_dir: Path, plant: str = "ideal") -> dict:
    proc = start_emulator(domain, rtf, log_dir, plant)
    client = RosTestClient("bench")
    try:
        stamps, walls = [], []
        clocks = []

        def on_state(msg):
            stamps.append(msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9)
            walls.append(time.monotonic())

        client.node.create_subscription(JointState, "legs/joint_states", on_state, 1000)
        client.node.create_subscription(Clock, "/clock", lambda m: clocks.append(m), 100)
        client.spin_until(lambda: len(stamps) > 50, 60)
        stamps.clear()
        walls.clear()
        client.spin_for(seconds)
        sim = stamps[-1] - stamps[0]
        wall = walls[-1] - walls[0]
        return {"real_time_factor_requested": rtf, "real_time_factor_achieved": sim / wall,
                "state_rate_hz_wall": (len(stamps) - 1) / wall, "state_rate_hz_sim": (len(stamps) - 1) / sim,
                "states_received": len(stamps)}
    finally:
        client.close()
        proc.stop()


def measure_max_speed(seconds: float, log_dir: Path, plant: str = "ideal") -> dict:
    """The emulator alone at real_time_factor 0 on ``plant``, on a domain of its own: achieved real-time factor."""
    domain, lock = claim_ros_domain()
    try:
        return measure_rtf_and_rate(domain, 0.0, seconds, log_dir, plant)
    finally:
        lock.close()


def measure_latency(domain: int, count: int, log_dir: Path) -> dict:
    robot = load_robot()
    home = inverse_kinematics(robot, robot.home_pose)
    proc = start_emulator(domain, 1.0, log_dir)
    client = RosTestClient("bench_latency")
    try:
        latest = {}

        def on_state(msg):
            latest["pos"] = np.array(msg.position[:6])
            latest["wall"] = time.monotonic()

        client.node.create_subscription(JointState, "legs/joint_states", on_state, 10)
        pub = client.publisher("legs/joint_trajectory", JointTrajectory)
        client.wait_for_subscribers("legs/joint_trajectory")
        client.spin_until(lambda: "pos" in latest, 60)
        latencies = []
        for k in range(count):
            target = home + (2e-6 if k % 2 == 0 else 0.0)
            msg = JointTrajectory(joint_names=LEGS)
            msg.points = [JointTrajectoryPoint(positions=target.tolist(), time_from_start=duration_msg(0.2))]
            before = latest["pos"].copy()
            sent = time.monotonic()
            pub.publish(msg)
            moved = client.spin_until(lambda b=before, s=sent: np.abs(latest["pos"] - b).max() > 1e-9 and
                                      latest["wall"] > s, 5)
            if moved:
                latencies.append(latest["wall"] - sent)
            client.spin_for(0.25)
        lat = np.array(latencies) * 1e3
        return {"latency_ms_p50": float(np.median(lat)), "latency_ms_p99": float(np.percentile(lat, 99)),
                "latency_ms_worst": sorted(lat.tolist())[-3:], "latency_samples": int(lat.size)}
    finally:
        client.close()
        proc.stop()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=8.0)
    parser.add_argument("--latency-samples", type=int, default=100)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    domain, _lock = claim_ros_domain()
    with tempfile.TemporaryDirectory() as tmp:
        fast = measure_rtf_and_rate(domain, 0.0, args.seconds, Path(tmp))
        real = measure_rtf_and_rate(domain, 1.0, args.seconds, Path(tmp))
        latency = measure_latency(domain, args.latency_samples, Path(tmp))
    results = {"max_speed": fast, "real_time": real, "latency": latency}
    if args.json:
        print(json.dumps(results, indent=2))
        return 0
    print("hardware emulator (MuJoCo semi-implicit Euler + strut servos, physics 2 kHz, states 500 Hz sim; "
          "suite_params.yaml)")
    print(f"  max real-time factor (real_time_factor 0): {fast['real_time_factor_achieved']:.2f}")
    print(f"  at real_time_factor 1: achieved {real['real_time_factor_achieved']:.3f}, joint states "
          f"{real['state_rate_hz_wall']:.1f} Hz wall ({real['state_rate_hz_wall'] / 500:.3f} of the 500 Hz target)")
    worst = ", ".join(f"{x:.1f}" for x in latency["latency_ms_worst"])
    print(f"  command-to-state latency: p50 {latency['latency_ms_p50']:.2f} ms, p99 {latency['latency_ms_p99']:.2f} ms "
          f"({latency['latency_samples']} samples; worst {worst} ms)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
