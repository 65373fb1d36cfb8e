"""The messaging floor of the suite's topology: the CPU that rclpy + Fast DDS alone cost for the
suite's 500 Hz streams, with no computation at all.

Starts five processes shaped like the suite (same executor, raw CDR publish/take, same QoS, the suite's
loopback DDS profile, each its own ROS domain participant):
- "emulator": publishes legs/joint_states and ground_truth/platform_pose at 500 Hz in bursts of 10 every 20 ms and
  /clock at 100 Hz (the real emulator's pacing), real message sizes;
- "kinematics": takes each joint state, publishes one platform/pose_estimate;
- "estimator": takes each joint state, publishes one legs/force_estimate and one external wrench;
- "planner": takes platform/pose_estimate;
- "recorder": takes all six streams and /clock, keeps the bytes.
Every callback only moves bytes. The total CPU (user + system, /proc) over the window is what the suite
would cost if kinematics, dynamics, physics and MCAP writing were free: compare it with
benchmarks/suite_cpu.py.

Run: .venv/bin/python benchmarks/dds_floor.py [--seconds 10]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

ROLES = ("emulator", "kinematics", "estimator", "planner", "recorder")
CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


def run_role(role: str, seconds: float) -> None:
    import numpy as np
    import rclpy
    from geometry_msgs.msg import PoseStamped, WrenchStamped
    from rclpy.node import Node
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState

    from stewart_vibration.messages import cdr
    from stewart_vibration.messages.joint_states import JointStateEncoder
    from stewart_vibration.messages.stamped_doubles import PoseStampedEncoder, WrenchStampedEncoder
    from stewart_vibration.nodes.run_loop import STREAM_DEPTH, make_executor, spin_until_stopped
    from stewart_vibration.robot import LEG_NAMES, VIB_NAMES

    rclpy.init()
    node = Node(f"floor_{role}")
    executor = make_executor()
    executor.add_node(node)
    states = JointStateEncoder(LEG_NAMES + VIB_NAMES)
    forces = JointStateEncoder(LEG_NAMES)
    poses = PoseStampedEncoder("base")
    six, quat = np.zeros(6), np.array([0.0, 0.0, 0.0, 1.0])
    kept = []

    def stamp_of(data: bytes) -> float:
        sec, nsec = int.from_bytes(data[4:8], "little"), int.from_bytes(data[8:12], "little")
        return sec + nsec * 1e-9

    if role == "emulator":
        js = node.create_publisher(JointState, "legs/joint_states", STREAM_DEPTH)
        pose = node.create_publisher(PoseStamped, "ground_truth/platform_pose", STREAM_DEPTH)
        clock = node.create_publisher(Clock, "/clock", 10)
        twelve = np.zeros(12)
        t0, k = time.monotonic(), 0

        def burst() -> None:
            nonlocal k
            now = time.monotonic() - t0
            while (k + 1) * 0.002 <= now:
                k += 1
                t = 1000.0 + k * 0.002
                js.publish(states.encode(t, twelve, twelve, twelve))
                pose.publish(poses.encode(t, six[:3], quat))
                if k % 5 == 0:
                    clock.publish(cdr.encode_clock(t))

        node.create_timer(0.02, burst)
    elif role == "kinematics":
        out = node.create_publisher(PoseStamped, "platform/pose_estimate", STREAM_DEPTH)
        node.create_subscription(JointState, "legs/joint_states",
                                 lambda d: out.publish(poses.encode(stamp_of(d), six[:3], quat)), STREAM_DEPTH,
                                 raw=True)
    elif role == "estimator":
        force = node.create_publisher(JointState, "legs/force_estimate", STREAM_DEPTH)
        wrench = node.create_publisher(WrenchStamped, "platform/external_wrench_estimate", STREAM_DEPTH)
        encode_wrench = WrenchStampedEncoder("base")

        def estimate(data: bytes) -> None:
            t = stamp_of(data)
            force.publish(forces.encode(t, six, six, six))
            wrench.publish(encode_wrench.encode(t, six))

        node.create_subscription(JointState, "legs/joint_states", estimate, STREAM_DEPTH, raw=True)
    elif role == "planner":
        node.create_subscription(PoseStamped, "platform/pose_estimate", kept.append, 10, raw=True)
    else:
        for topic, kind in (("legs/joint_states", JointState), ("ground_truth/platform_pose", PoseStamped),
                            ("platform/pose_estimate", PoseStamped), ("legs/force_estimate", JointState),
                            ("platform/external_wrench_estimate", WrenchStamped), ("/clock", Clock)):
            node.create_subscription(kind, topic, kept.append, STREAM_DEPTH, raw=True)
    import threading

    stop = threading.Event()
    threading.Timer(seconds, stop.set).start()
    spin_until_stopped(executor, stop)
    print(f"{role} done ({len(kept)} kept)", flush=True)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=10.0, help="measurement window, s")
    parser.add_argument("--role", choices=ROLES, help=argparse.SUPPRESS)
    parser.add_argument("--run-seconds", type=float, default=0.0, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.role:
        run_role(args.role, args.run_seconds)
        return 0
    cores = measure_floor(args.seconds)
    print(f"Messaging floor of the suite's topology (no computation), {args.seconds:.1f} s:")
    for role in ROLES:
        print(f"  {role:<12}{cores[role]:7.3f} cores")
    print(f"  {'total':<12}{sum(cores.values()):7.3f} cores (the suite's required total is 0.5)")
    return 0


def measure_floor(seconds: float) -> dict[str, float]:
    """Cores per role of the messaging floor over ``seconds`` (after a 3 s warm-up), on a domain of its own."""
    from stewart_vibration.runtime.processes import claim_ros_domain, ros_environment

    domain, lock = claim_ros_domain()
    env = ros_environment(domain)
    warmup = 3.0
    procs = {role: subprocess.Popen([sys.executable, __file__, "--role", role, "--run-seconds",
                                     str(seconds + warmup + 2.0)], env=env) for role in ROLES}
    time.sleep(warmup)
    start = {role: cpu_seconds(p.pid) for role, p in procs.items()}
    wall0 = time.monotonic()
    time.sleep(seconds)
    end = {role: cpu_seconds(p.pid) for role, p in procs.items()}
    wall = time.monotonic() - wall0
    for p in procs.values():
        p.wait(timeout=60)
    lock.close()
    return {role: (end[role] - start[role]) / wall for role in ROLES}


if __name__ == "__main__":
    sys.exit(main())
