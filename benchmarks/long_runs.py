"""Run summary and report of long recordings: time and peak memory against the recording's length.

    python benchmarks/long_runs.py [--minutes 1 10 60] [--keep DIR]

Synthesises a recording of each length with the main job's streams and rates (sensed and true joint states,
true pose, pose estimate, leg-force estimate, external-wrench estimate and IMU at 500 Hz, /clock at 100 Hz;
serialized as the nodes do, zstd chunks as the recorder writes), the units vibrating at 35 Hz throughout, one
vibration window stamped at its start. Then, each in a process of its own, it computes the run summary's figures
as the main job does (the signals every figure is computed from, the recording's coverage, the streams, the limit
check over every state, and the figures of the one vibration that lasts the whole run: its ends held, its middle
summed in a second read: "summary") and writes the report (``stewart-vibration report``), and prints per length
the file's size, the wall time and peak resident memory of both, and the times as shares of the run's length.
One JSON line per length, then a table.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from stewart_vibration.mcap_log.writer import BagFileWriter
from stewart_vibration.messages import cdr
from stewart_vibration.messages.joint_states import JointStateEncoder
from stewart_vibration.messages.joint_trajectory import encode_joint_trajectory
from stewart_vibration.messages.stamped_doubles import ImuEncoder, PoseStampedEncoder, WrenchStampedEncoder
from stewart_vibration.robot import LEG_NAMES, VIB_NAMES

STATE_HZ, CLOCK_HZ, VIBRATION_HZ = 500, 100, 35.0
VIBRATION_T0 = 1.0  # s: the vibration's start (its one window's stamp); it lasts until 1 s before the end
NS = "/stewart/"


def synthesize(path: Path, seconds: float) -> int:
    """Write a recording of ``seconds`` (s) to ``path``; returns its message count."""
    writer = BagFileWriter(path)
    joint_state, pose_stamped = "sensor_msgs/msg/JointState", "geometry_msgs/msg/PoseStamped"
    types = {"legs/joint_states": joint_state, "ground_truth/joint_states": joint_state,
             "ground_truth/platform_pose": pose_stamped, "platform/pose_estimate": pose_stamped,
             "legs/force_estimate": joint_state, "platform/external_wrench_estimate": "geometry_msgs/msg/WrenchStamped",
             "platform/imu": "sensor_msgs/msg/Imu"}
    for name, type_name in types.items():
        writer.add_topic(NS + name, type_name, "[]")
    writer.add_topic("/clock", "rosgraph_msgs/msg/Clock", "[]")
    writer.add_topic(NS + "vibration/joint_trajectory", "trajectory_msgs/msg/JointTrajectory", "[]")
    states = JointStateEncoder(LEG_NAMES + VIB_NAMES, "base")
    forces = JointStateEncoder(LEG_NAMES, "base", fields=("effort",))
    pose, wrench, imu = PoseStampedEncoder("base"), WrenchStampedEncoder("base"), ImuEncoder("platform")
    rng = np.random.default_rng(1)
    amplitude = rng.uniform(5e-6, 2e-5, 6)
    phase = rng.choice([0.0, np.pi], 6)
    count = 0
    for block in range(int(np.ceil(seconds))):  # one second at a time: the arrays stay small
        t = block + np.arange(STATE_HZ) / STATE_HZ
        t = t[t < seconds]
        vib = amplitude * np.sin(2 * np.pi * VIBRATION_HZ * t[:, None] + phase)
        legs = 0.45 + 1e-4 * np.sin(0.1 * t[:, None]) + vib
        effort = 80.0 + 5.0 * np.sin(2 * np.pi * VIBRATION_HZ * t[:, None] + phase)
        z = 0.3 + 2e-5 * np.sin(2 * np.pi * VIBRATION_HZ * t)
        for i, ti in enumerate(t):
            log = round(ti * 1e9) + 300_000
            if abs(ti - VIBRATION_T0) < 0.5 / STATE_HZ:
                writer.write(NS + "vibration/joint_trajectory", log,
                             encode_joint_trajectory(VIB_NAMES, VIBRATION_T0, [0.0, 1.0], np.zeros((2, 6))))
                count += 1
            position = np.concatenate([legs[i], vib[i]])
            for name in ("legs/joint_states", "ground_truth/joint_states"):
                writer.write(NS + name, log, states.encode(ti, position, np.zeros(12), np.concatenate([effort[i],
                                                                                                    np.zeros(6)])))
            for name in ("ground_truth/platform_pose", "platform/pose_estimate"):
                writer.write(NS + name, log, pose.encode(ti, [0.0, 0.0, z[i]], [0.0, 0.0, 0.0, 1.0]))
            writer.write(NS + "legs/force_estimate", log, forces.encode(ti, effort=effort[i]))
            writer.write(NS + "platform/external_wrench_estimate", log, wrench.encode(ti, np.zeros(6)))
            writer.write(NS + "platform/imu", log, imu.encode(ti, np.zeros(3), [0.0, 0.0, 9.81]))
            count += 7
            if i % (STATE_HZ // CLOCK_HZ) == 0:
                writer.write("/clock", log, cdr.encode_clock(ti))
                count += 1
    writer.finish()
    return count


def run_figures(path: str, seconds: float) -> None:
    """The run summary's figures of a recording of ``seconds`` (s), read as the main job's summary reads a run:
    the signals, what the recording covers, the streams, the limit check over every recorded state, and the
    vibration's figures (its settings as the planner's defaults with its duration)."""
    from stewart_vibration.analysis.run_coverage import recording_coverage, stream_summary
    from stewart_vibration.analysis.run_signals import load_signals
    from stewart_vibration.analysis.run_verdict import limit_summary
    from stewart_vibration.analysis.vibration_figures import summarize_vibration, vibration_frame
    from stewart_vibration.analysis.vibration_scan import held_windows, stream_steady
    from stewart_vibration.cli.run_analysis import WINDOW_MARGIN_S
    from stewart_vibration.kinematics.robot_config import load_robot
    from stewart_vibration.paper import paper_pose
    from stewart_vibration.vibration.settings import default_settings

    robot = load_robot()
    settings = dict(default_settings(robot), frequency_hz=VIBRATION_HZ, duration_s=seconds - 2 * VIBRATION_T0)
    windows, spans = held_windows([(VIBRATION_T0, settings["duration_s"])], WINDOW_MARGIN_S)
    signals = load_signals(path, windows=windows, robot=robot)
    recording_coverage(signals, None)
    stream_summary(signals)
    limit_summary(robot, signals)
    frame = vibration_frame(robot, signals, paper_pose(robot), settings, VIBRATION_T0)
    (stream,) = stream_steady(path, [(frame, spans[0])])
    summarize_vibration(robot, signals, paper_pose(robot), settings, VIBRATION_T0, stream)


def measured(command: list[str]) -> tuple[float, float]:
    """(wall time s, peak resident memory MB) of ``command`` run to its end (raises if it fails)."""
    start = time.perf_counter()
    proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _pid, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"{command} failed: {proc.stderr.read().decode()[-2000:] if proc.stderr else ''}")
    return wall, usage.ru_maxrss / 1024.0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, nargs="+", default=[1.0, 10.0, 60.0])
    ap.add_argument("--keep", type=Path, default=None, help="write the recordings here and keep them")
    ap.add_argument("--figures-of", default=None, help=argparse.SUPPRESS)  # the measured child process
    ap.add_argument("--seconds", type=float, default=None, help=argparse.SUPPRESS)  # its recording's length
    args = ap.parse_args()
    if args.figures_of:
        run_figures(args.figures_of, args.seconds)
        return 0
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        where = args.keep or Path(tmp)
        for minutes in args.minutes:
            path = where / f"run_{minutes:g}min.mcap"
            start = time.perf_counter()
            count = synthesize(path, minutes * 60.0)
            made_s = time.perf_counter() - start
            summary_s, summary_mb = measured([sys.executable, __file__, "--figures-of", str(path), "--seconds",
                                                    str(minutes * 60.0)])
            report_s, report_mb = measured([sys.executable, "-m", "stewart_vibration", "report", str(path), "--out",
                                            str(where / f"report_{minutes:g}min")])
            row = {"minutes": minutes, "messages": count, "mcap_mb": round(path.stat().st_size / 1e6, 1),
                   "synthesized_s": round(made_s, 1), "summary_s": round(summary_s, 2),
                   "summary_peak_mb": round(summary_mb), "report_s": round(report_s, 2),
                   "report_peak_mb": round(report_mb), "summary_share_of_run": round(summary_s / (minutes * 60.0), 4),
                   "report_share_of_run": round(report_s / (minutes * 60.0), 4)}
            rows.append(row)
            print(json.dumps(row), flush=True)
            if args.keep is None:
                path.unlink()
    print("\n| run | MCAP | summary: time, peak memory | report: time, peak memory | time / run length: summary, "
          "report |")
    print("|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['minutes']:g} min | {r['mcap_mb']} MB | {r['summary_s']} s, {r['summary_peak_mb']} MB | "
              f"{r['report_s']} s, {r['report_peak_mb']} MB | {100 * r['summary_share_of_run']:.1f} %, "
              f"{100 * r['report_share_of_run']:.1f} % |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
