"""Test scaffolding: publish a short synthetic run on the suite's topics (recorder tests, benchmarks).

Not part of the product graph: it stands in for the emulator / estimator where a
test wants exact, known messages. Messages are real ROS types with plausible values:
legs/joint_states (leg_1..6 lengths, vib_1..6 displacements, efforts in N),
ground_truth/platform_pose, legs/force_estimate, /diagnostics events, optional /clock.

    PYTHONPATH=test python -m synthetic_run_publisher --count 200 --rate 100

Waits until every publisher has a subscriber (the recorder), publishes
``count`` samples per topic at ``rate`` Hz, then prints one line
``SYNTHETIC_SENT {json counts}``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

import rclpy
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from stewart_vibration.robot import LEG_NAMES, VIB_NAMES


def _stamp(t_ns: int) -> Time:
    return Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000)


def _joint_states(t: float, stamp: Time) -> JointState:
    msg = JointState()
    msg.header.stamp = stamp
    msg.name = [*LEG_NAMES, *VIB_NAMES]
    w = 2 * math.pi * 20.0
    lengths = [0.30 + 0.002 * i + 1e-4 * math.sin(w * t + 0.3 * i) for i in range(6)]
    vib = [5e-4 * (1 - 0.1 * i) * math.sin(w * t + 0.2 * i) for i in range(6)]
    msg.position = lengths + vib
    msg.velocity = [1e-4 * w * math.cos(w * t + 0.3 * i) for i in range(6)] + [
        5e-4 * (1 - 0.1 * i) * w * math.cos(w * t + 0.2 * i) for i in range(6)
    ]
    msg.effort = [40.0 + 5 * i + 3 * math.sin(w * t + 0.5 * i) for i in range(6)] + [0.0] * 6
    return msg


def _pose(t: float, stamp: Time) -> PoseStamped:
    msg = PoseStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = "base"
    a = 5e-4 * math.sin(2 * math.pi * 20.0 * t)
    msg.pose.position.x = 0.3 * a
    msg.pose.position.y = 0.1 * a
    msg.pose.position.z = 0.25 + 0.95 * a
    msg.pose.orientation.w = 1.0
    return msg


def _forces(t: float, stamp: Time) -> JointState:
    msg = JointState()
    msg.header.stamp = stamp
    msg.name = list(LEG_NAMES)
    msg.effort = [40.0 + 5 * i + 3 * math.sin(2 * math.pi * 20.0 * t + 0.5 * i) + 0.2 for i in range(6)]
    return msg


def _diag(stamp: Time, text: str, level: bytes) -> DiagnosticArray:
    msg = DiagnosticArray()
    msg.header.stamp = stamp
    status = DiagnosticStatus(level=level, name="vibration_planner", message=text)
    status.values = [KeyValue(key="event", value=text)]
    msg.status = [status]
    return msg


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=100, help="samples per topic")
    parser.add_argument("--rate", type=float, default=100.0, help="Hz")
    parser.add_argument("--topics", default="joint_states,pose,force,diag", help="comma list; add clock")
    parser.add_argument("--fast", action="store_true", help="reuse one joint_states message (benchmarks)")
    parser.add_argument("--wait-s", type=float, default=20.0, help="max wait for subscribers")
    parser.add_argument("--start-s", type=float, default=1000.0, help="stamp of the first sample (sim s)")
    args = parser.parse_args(rclpy.utilities.remove_ros_args(sys.argv[1:] if argv is None else argv))
    rclpy.init()
    node = Node("synthetic_run_publisher")
    kinds = set(args.topics.split(","))
    pubs = {}
    if "joint_states" in kinds:
        pubs["joint_states"] = node.create_publisher(JointState, "legs/joint_states", 1000)
    if "pose" in kinds:
        pubs["pose"] = node.create_publisher(PoseStamped, "ground_truth/platform_pose", 1000)
    if "force" in kinds:
        pubs["force"] = node.create_publisher(JointState, "legs/force_estimate", 1000)
    if "diag" in kinds:
        pubs["diag"] = node.create_publisher(DiagnosticArray, "/diagnostics", 100)
    if "clock" in kinds:
        pubs["clock"] = node.create_publisher(Clock, "/clock", 100)
    deadline = time.monotonic() + args.wait_s
    while time.monotonic() < deadline and any(p.get_subscription_count() == 0 for p in pubs.values()):
        time.sleep(0.05)
    time.sleep(0.3)  # let the matched reader finish its handshake
    sent = {name: 0 for name in pubs}
    t0 = time.perf_counter()
    sim0 = round(args.start_s * 1e9)  # default 1000 s, a recognisable sim-time origin
    fixed = None  # --fast: one JointState reused with a new stamp
    for i in range(args.count):
        target = t0 + i / args.rate
        while (now := time.perf_counter()) < target:
            if target - now > 0.002:
                time.sleep(target - now - 0.001)
        t = i / args.rate
        stamp = _stamp(sim0 + round(t * 1e9))
        if "clock" in pubs:
            pubs["clock"].publish(Clock(clock=stamp))
        if "joint_states" in pubs:
            if args.fast:
                fixed = fixed if fixed is not None else _joint_states(0.0, stamp)
                fixed.header.stamp = stamp
                pubs["joint_states"].publish(fixed)
            else:
                pubs["joint_states"].publish(_joint_states(t, stamp))
        if "pose" in pubs:
            pubs["pose"].publish(_pose(t, stamp))
        if "force" in pubs:
            pubs["force"].publish(_forces(t, stamp))
        if "diag" in pubs and i in (0, args.count // 2, args.count - 1):
            text = {0: "vibration started", args.count - 1: "vibration stopped"}.get(i, "e-stop test")
            level = DiagnosticStatus.OK if i != args.count // 2 else DiagnosticStatus.WARN
            pubs["diag"].publish(_diag(stamp, text, level))
        for name in sent:
            if name != "diag":
                sent[name] += 1
            elif i in (0, args.count // 2, args.count - 1):
                sent[name] += 1
    rate = args.count / max(time.perf_counter() - t0, 1e-9)
    time.sleep(0.5)  # reliable delivery of the tail
    topic_of = {
        "joint_states": "legs/joint_states",
        "pose": "ground_truth/platform_pose",
        "force": "legs/force_estimate",
        "diag": "/diagnostics",
        "clock": "/clock",
    }
    counts = {node.resolve_topic_name(topic_of[k]): v for k, v in sent.items()}
    print("SYNTHETIC_SENT " + json.dumps({"counts": counts, "rate_hz": rate}), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
