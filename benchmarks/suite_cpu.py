"""CPU headroom of the whole node suite at real time.

Runs the main job (`stewart-vibration run`, every node its own process over real DDS) with a long
vibration, and during the steady part of the vibration samples each process's CPU time (user +
system, /proc/<pid>/stat) over a window of wall time: cores used = CPU seconds / wall seconds, per
node and in total (the runner included). Then reads the run's summary for the sample counts per
topic and the output lag, and measures the emulator alone at real_time_factor 0 (its maximum
real-time factor, benchmarks/emulator.py).

By default it does so on the ideal plant (the drawing) and on the realistic one (the robot as built,
config/plant_realistic.yaml) in turn, and compares them: the realistic suite may cost at most 1.25x the ideal
one, and its emulator must run at least half as fast.

Run: .venv/bin/python benchmarks/suite_cpu.py [--vibration 25] [--window 15] [--plants ideal,realistic] [--json]
Exit code 0 when every required figure is met (on the ideal plant: total within 0.5 cores and the run passed;
on both: every estimate per state and a summary; the two ratios); 1 otherwise.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

REQUIRED_CORES, GOAL_CORES = 0.5, 0.25
LAG_GOAL_MS = 20.0
SAMPLE_RATIO_MIN = 0.999  # on a quiet machine every state gives its estimates
CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float | None:
    """User + system CPU time (s) of a process (all its threads), None if it is gone."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


def children(pid: int) -> list[int]:
    """All descendants of a process (recursively)."""
    out = []
    try:
        direct = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
    except OSError:
        return out
    for child in map(int, direct):
        out += [child, *children(child)]
    return out


def process_name(pid: int) -> str:
    try:
        cmd = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
    except OSError:
        return "?"
    text = " ".join(c.decode(errors="replace") for c in cmd if c)
    match = re.search(r"stewart_vibration\.nodes\.(\w+)", text)
    if match:
        return match.group(1).removesuffix("_node")
    if "stewart_vibration run" in text or text.endswith(" run") or " run " in text:
        return "runner"
    return Path(cmd[0].decode(errors="replace")).name or "?"


LAG_TOPICS = ("legs/joint_states", "platform/pose_estimate", "legs/force_estimate",
              "platform/external_wrench_estimate")
LAG_TYPES = {"legs/joint_states": "sensor_msgs/msg/JointState",
             "platform/pose_estimate": "geometry_msgs/msg/PoseStamped",
             "legs/force_estimate": "sensor_msgs/msg/JointState",
             "platform/external_wrench_estimate": "geometry_msgs/msg/WrenchStamped"}


def probe_lag(domain: int, seconds: float, estimate: str, namespace: str = "/stewart") -> dict:
    """Lag of one estimate stream, measured by a separate reader of the states and that estimate only (its own
    process's DDS participant; the single-threaded executor, so each callback gets the message's DDS timestamps).

    The estimate's lag runs from the publication of the state with the same header stamp (that state's DDS source
    timestamp, the emulator's wall clock) to the estimate's reception by this reader's participant (its received
    timestamp), split into its node's part (the state's publication to the estimate's: the node's input queue
    and processing) and the second hop (the estimate's publication to its reception). A reader of every stream
    at once (2,000 messages per second into one Python process) measured itself: its second hop reached p99
    0.4-1.7 s while readers of two streams saw 1-3 ms on most runs, and the nodes' part stayed at p99 11-20 ms.

    Returns:
        {"legs/joint_states": {p50, p99, max, count} (their DDS transit), estimate: {..., "node": {...},
        "second_hop": {...}}} (ms); {} when nothing arrived.
    """
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from stewart_vibration.messages.cdr import header_stamp_ns
    from stewart_vibration.nodes.ros_graph import message_class
    from stewart_vibration.nodes.run_loop import STREAM_DEPTH
    from stewart_vibration.runtime.processes import ros_environment

    os.environ.update(ros_environment(domain))  # the suite's DDS profile (loopback), before the first participant
    topics = ("legs/joint_states", estimate)
    context = Context()
    context.init(domain_id=domain)
    node = Node("lag_probe", namespace=namespace, context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    seen: dict = {topic: [] for topic in topics}

    def on_message(data, info, topic):
        seen[topic].append((header_stamp_ns(data), info["source_timestamp"], info["received_timestamp"]))

    for topic in topics:
        node.create_subscription(message_class(LAG_TYPES[topic]), topic,
                                 lambda data, info, t=topic: on_message(data, info, t), STREAM_DEPTH, raw=True)

    def spin(duration: float) -> None:
        end = time.monotonic() + duration
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.05)

    matched_by = time.monotonic() + 20.0  # discovery and matching, then a second for the history to drain
    while time.monotonic() < matched_by and min(node.count_publishers(t) for t in topics) < 1:
        spin(0.1)
    spin(1.0)
    for rows in seen.values():
        rows.clear()
    spin(seconds)
    node.destroy_node()
    context.try_shutdown()
    states = [row for row in seen["legs/joint_states"] if row[0] is not None]
    if not states:
        return {}
    published = {stamp: source for stamp, source, _received in states}
    out = {"legs/joint_states": _percentiles(np.array([received - source for _s, source, received in states]) * 1e-6)}
    paired = np.array([(published[stamp], source, received) for stamp, source, received in seen[estimate]
                       if stamp in published], dtype=float).reshape(-1, 3) * 1e-6
    if paired.size:
        out[estimate] = _percentiles(paired[:, 2] - paired[:, 0])
        out[estimate]["node"] = _percentiles(paired[:, 1] - paired[:, 0])
        out[estimate]["second_hop"] = _percentiles(paired[:, 2] - paired[:, 1])
    return out


def _percentiles(d_ms: np.ndarray) -> dict:
    return {"p50": float(np.percentile(d_ms, 50)), "p99": float(np.percentile(d_ms, 99)), "max": float(d_ms.max()),
            "count": int(d_ms.size)}


def measure_lag(domain: int, seconds: float) -> dict:
    """The end-to-end lag of every estimate stream (``probe_lag``, one reader per estimate, ``seconds`` / 3
    each), and the states' transit as the first reader saw it. Returns {topic: {p50, p99, max, count, ...}} (ms)."""
    out: dict = {}
    for estimate in LAG_TOPICS[1:]:
        for topic, row in probe_lag(domain, seconds / (len(LAG_TOPICS) - 1), estimate).items():
            out.setdefault(topic, row)
    return out


def start_vibrating(vibration_s: float, out: Path, plant: str = "ideal"):
    """The main job started with a vibration of ``vibration_s`` (s) on its own ROS domain, returned once it
    vibrates: (its process, the lines it printed so far (still growing), the domain, the domain's lock)."""
    from stewart_vibration.runtime.processes import claim_ros_domain

    domain, lock = claim_ros_domain()
    cmd = [sys.executable, "-m", "stewart_vibration", "run", "--duration", str(vibration_s), "--out", str(out),
           "--domain-id", str(domain), "--plant", plant]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1,
                            start_new_session=True)
    lines: list[str] = []
    vibrating = threading.Event()

    def read() -> None:
        for line in proc.stdout or []:
            lines.append(line)
            if ": vibrating: started" in line:
                vibrating.set()

    threading.Thread(target=read, daemon=True).start()
    if not vibrating.wait(timeout=180):
        proc.kill()
        raise RuntimeError("the vibration never started:\n" + "".join(lines[-30:]))
    return proc, lines, domain, lock


def measure_suite(vibration_s: float, window_s: float, out: Path, settle_s: float = 3.0,
                  lag_s: float = 7.5, plant: str = "ideal") -> dict:
    proc, lines, domain, lock = start_vibrating(vibration_s, out, plant)
    time.sleep(settle_s)
    pids = [proc.pid, *children(proc.pid)]
    names = {pid: process_name(pid) for pid in pids}
    names[proc.pid] = "runner"
    start = {pid: cpu_seconds(pid) for pid in pids}
    wall0 = time.monotonic()
    time.sleep(window_s)
    end = {pid: cpu_seconds(pid) for pid in pids}
    wall = time.monotonic() - wall0
    per_node: dict[str, float] = {}
    for pid in pids:
        if start[pid] is None or end[pid] is None:
            continue
        per_node[names[pid]] = per_node.get(names[pid], 0.0) + (end[pid] - start[pid]) / wall
    # after the CPU window (an extra reader loads the publishers), while the vibration still runs
    lag = measure_lag(domain, lag_s) if vibration_s > settle_s + window_s + lag_s + 2.0 else {}
    code = proc.wait(timeout=600)
    lock.close()
    time.sleep(0.5)  # the last lines reach ``lines``
    summary_path = out / "summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.exists() else {}
    return {"exit_code": code, "window_s": wall, "cores": per_node, "total_cores": sum(per_node.values()),
            "lag_ms": lag, "summary": summary, "log_tail": "".join(lines[-12:])}


PLANT_CPU_RATIO_MAX = 1.25  # the suite on the robot as built costs at most this much more than on the drawing
PLANT_SPEED_RATIO_MIN = 0.5  # and its emulator runs at least half as fast


def measure_plant(plant: str, args, tmp: Path) -> dict:
    """The suite at real time and the emulator alone at its maximum speed, both on ``plant``."""
    suite = measure_suite(args.vibration, args.window, tmp / f"run_{plant}", plant=plant)
    from emulator import measure_max_speed  # noqa: E402 - the emulator benchmark's measurement

    emulator = measure_max_speed(args.emulator_seconds, tmp, plant)
    summary = suite.pop("summary")
    return {"suite": suite, "streams": summary.get("streams", {}), "summarised": bool(summary),
            "bound_failures": summary.get("bound_failures"), "emulator_max": emulator}


def plant_verdicts(plant: str, row: dict) -> list[tuple[str, bool, bool]]:
    """(figure, required?, met?) of one plant. On the drawing the main job must pass its bounds; on the robot as
    built today's controller misses them (that is what the vibration-control work fixes), so there the run
    must only end with its summary."""
    suite, total = row["suite"], row["suite"]["total_cores"]
    worst_ratio = row["streams"].get("worst_ratio", 0.0)
    lag = suite["lag_ms"]
    worst_lag = max((r["p99"] for topic, r in lag.items() if topic != "legs/joint_states"), default=None)
    rtf = row["emulator_max"]["real_time_factor_achieved"]
    ideal = plant == "ideal"
    return [
        (f"{plant}: suite CPU {total:.3f} cores <= {REQUIRED_CORES}", ideal, total <= REQUIRED_CORES),
        (f"{plant}: estimates per joint state {worst_ratio * 100:.3f} % >= {SAMPLE_RATIO_MIN * 100:g} %", True,
         worst_ratio >= SAMPLE_RATIO_MIN),
        (f"{plant}: main job exit code {suite['exit_code']} (every scenario bound)", ideal, suite["exit_code"] == 0),
        (f"{plant}: main job wrote its summary", True, row["summarised"]),
        (f"{plant}: suite CPU {total:.3f} cores <= {GOAL_CORES} (goal)", False, total <= GOAL_CORES),
        (f"{plant}: end-to-end lag p99 {worst_lag if worst_lag is not None else float('nan'):.1f} ms <= "
         f"{LAG_GOAL_MS:g} ms (goal)", False, worst_lag is not None and worst_lag <= LAG_GOAL_MS),
        (f"{plant}: emulator max real-time factor {rtf:.2f} >= 10 (goal)", False, rtf >= 10.0),
    ]


def comparison_verdicts(rows: dict) -> list[tuple[str, bool, bool]]:
    """The realistic plant against the ideal one (both measured in this run)."""
    if not {"ideal", "realistic"} <= rows.keys():
        return []
    cpu = rows["realistic"]["suite"]["total_cores"] / rows["ideal"]["suite"]["total_cores"]
    speed = (rows["realistic"]["emulator_max"]["real_time_factor_achieved"]
             / rows["ideal"]["emulator_max"]["real_time_factor_achieved"])
    return [(f"suite CPU realistic / ideal {cpu:.3f}x <= {PLANT_CPU_RATIO_MAX}x", True, cpu <= PLANT_CPU_RATIO_MAX),
            (f"emulator max real-time factor realistic / ideal {speed:.3f} >= {PLANT_SPEED_RATIO_MIN}", True,
             speed >= PLANT_SPEED_RATIO_MIN)]


def print_plant(plant: str, row: dict) -> None:
    suite, streams, lag = row["suite"], row["streams"], row["suite"]["lag_ms"]
    total, emulator = suite["total_cores"], row["emulator_max"]
    print(f"Plant {plant}: whole suite at real_time_factor 1, {suite['window_s']:.1f} s of steady vibration "
          "(35 Hz, 0.3 g):")
    print(f"  {'process':<22}{'cores':>8}")
    for name, cores in sorted(suite["cores"].items(), key=lambda kv: -kv[1]):
        print(f"  {name:<22}{cores:8.3f}")
    print(f"  {'total':<22}{total:8.3f}   (required <= {REQUIRED_CORES}, goal {GOAL_CORES}: "
          f"{'meets the goal' if total <= GOAL_CORES else f'{total / GOAL_CORES:.2f}x the goal'})")
    if streams:
        print("  Samples per topic over the run (vs legs/joint_states):")
        for topic, r in streams.get("topics", {}).items():
            print(f"    {topic:<36}{r['count']:8d}  {r['ratio'] * 100:8.3f} %")
        print("  Each node's input (its own diagnostics): received, lost, processing lag (arrival -> output, ms):")
        for node, r in streams.get("nodes", {}).items():
            print(f"    {node:<22}{r['received']:8d} received, {r['lost']} lost, lag p50 {r['lag_p50_ms']:.2f}"
                  f" / p99 {r['lag_p99_ms']:.2f}")
    if lag:
        print(f"  End-to-end lag (DDS timestamps: the state's publication to the estimate's reception by a separate "
              f"reader of the states and that estimate; the states' own row: their transit; ms; goal p99 <= "
              f"{LAG_GOAL_MS:g}):")
        for topic, r in lag.items():
            print(f"    {topic:<36}p50 {r['p50']:6.2f}  p99 {r['p99']:6.2f}  max {r['max']:6.2f}  "
                  f"({r['count']} messages)")
            for part, what in (("node", "its node (state sent -> estimate sent)"),
                               ("second_hop", "second hop (estimate sent -> received)")):
                if part in r:
                    print(f"      {what:<45}p50 {r[part]['p50']:6.2f}  p99 {r[part]['p99']:6.2f}")
    else:
        print("  End-to-end lag: not measured (the vibration was too short for a window after the CPU window)")
    print(f"  Emulator alone (real_time_factor 0): max real-time factor {emulator['real_time_factor_achieved']:.2f} "
          f"(goal >= 10), {emulator['state_rate_hz_wall']:.0f} joint states per wall second")
    print(f"  main job exit code {suite['exit_code']}; bound failures: {row['bound_failures']}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--vibration", type=float, default=28.0, help="vibration duration of the run, s")
    parser.add_argument("--window", type=float, default=15.0, help="CPU sampling window during the vibration, s")
    parser.add_argument("--emulator-seconds", type=float, default=6.0, help="max real-time factor measurement, s")
    parser.add_argument("--plants", default="ideal,realistic",
                        help="comma-separated plants, each measured in turn (default: ideal,realistic, and their "
                             "ratios)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    plants = [p.strip() for p in args.plants.split(",") if p.strip()]
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    with tempfile.TemporaryDirectory() as tmp:
        rows = {plant: measure_plant(plant, args, Path(tmp)) for plant in plants}
    verdicts = [v for plant, row in rows.items() for v in plant_verdicts(plant, row)] + comparison_verdicts(rows)
    ok = all(met for _, required, met in verdicts if required)
    result = {"plants": rows, "verdicts": [{"figure": f, "required": r, "met": m} for f, r, m in verdicts]}
    if args.json:
        print(json.dumps(result, indent=2))
        return 0 if ok else 1
    for plant, row in rows.items():
        print_plant(plant, row)
    if {"ideal", "realistic"} <= rows.keys():
        print("Realistic against ideal (cores per process):")
        ideal, real = rows["ideal"]["suite"]["cores"], rows["realistic"]["suite"]["cores"]
        for name in sorted(ideal, key=lambda n: -ideal[n]):
            if name in real and ideal[name] > 0:
                print(f"  {name:<22}{ideal[name]:8.3f}{real[name]:8.3f}   {real[name] / ideal[name]:.2f}x")
    print("Verdict (exit code 0 when every required figure is met; goals are reported, not required):")
    for figure, required, met in verdicts:
        print(f"  {'ok  ' if met else ('FAIL' if required else 'miss')}  {figure}")
    print("PASS" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
