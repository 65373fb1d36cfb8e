"""``stewart-vibration run``: the main job. Brings up the whole node suite (each node its own
process, sim time, own ROS domain), runs a scenario, logs an MCAP, writes the report and prints
a summary checked against the scenario's bounds.

Exit codes: 0 all steps done and every figure within its bound; 1 a figure missed its bound;
2 a step failed (or bad input); 130 interrupted (Ctrl-C / SIGTERM).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from ..robot import load_robot
from ..scenario import load_scenario
from .output import to_jsonable


def register(subparsers) -> None:
    cmd = subparsers.add_parser("run", help="bring up the node suite in emulation and run a scenario (main job)")
    cmd.add_argument("--scenario", help="scenario YAML (default: config/scenario_paper.yaml)")
    cmd.add_argument("--duration", type=float, help="override every vibration's duration (s, incl. ramps)")
    cmd.add_argument("--real-time-factor", type=float, default=1.0,
                     help="sim seconds per wall second (default 1; 0 = as fast as the machine can)")
    cmd.add_argument("--out", default="runs/latest", help="output directory (MCAP, logs, report)")
    cmd.add_argument("--domain-id", type=int, default=None, help="ROS_DOMAIN_ID (default: 40 + pid %% 50)")
    cmd.add_argument("--namespace", default="/stewart", help="namespace of every node (default /stewart)")
    cmd.add_argument("--keep-running", action="store_true",
                     help="after the scenario keep the nodes up for a UI until Ctrl-C")
    cmd.add_argument("--json", action="store_true", help="print the summary as JSON")
    cmd.set_defaults(func=run)


def _log(message: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {message}", flush=True)


def _on_sigterm(signum, frame):
    raise KeyboardInterrupt


def run(args) -> int:
    from ..nodes.suite_runner import RunOptions, StepFailed, SuiteRunner  # rclpy only here, lazily
    from ..run_summary import check_bounds, load_signals, summarize_vibration

    robot = load_robot(args.robot)
    scenario = load_scenario(robot, args.scenario, args.duration)
    out = Path(args.out)
    domain = args.domain_id if args.domain_id is not None else 40 + os.getpid() % 50
    options = RunOptions(namespace=args.namespace, domain_id=domain, real_time_factor=args.real_time_factor,
                         out_dir=out, progress=_log)
    signal.signal(signal.SIGTERM, _on_sigterm)
    runner = SuiteRunner(options)
    status, failure = 0, None
    _log(f"scenario '{scenario.name}' ({scenario.source}); ROS_DOMAIN_ID={domain}, namespace {args.namespace}, "
         f"real-time factor {args.real_time_factor or 'max'}; output {out.resolve()}")
    try:
        runner.start()
        runner.wait_ready()
        runner.run(scenario)
        if args.keep_running:
            _print_ui_help(args.namespace, domain)
            while all(p.alive() for p in runner.procs):
                runner.executor.spin_once(timeout_sec=0.5)
            _log("a node exited; shutting down")
    except KeyboardInterrupt:
        runner.record.interrupted = True
        status = 130
        _log("interrupted: stopping the recorder and every node")
    except StepFailed as exc:
        status, failure = 2, str(exc)
        _log(f"FAILED: {exc}")
    finally:
        runner.stop()
    record = runner.record
    _log(f"all nodes stopped; MCAP: {record.mcap_path}")
    if record.mcap_path is None:
        _log("no MCAP was written")
        return status or 2
    summary = {"scenario": scenario.name, "mcap": str(record.mcap_path), "moves": record.moves,
               "vibrations": [], "failure": failure, "interrupted": record.interrupted}
    if not record.interrupted and failure is None:
        signals = load_signals(record.mcap_path)
        nominal = robot.home_pose
        for step_move, vib in _pair_vibrations(record):
            nominal = np.asarray(step_move["target"]) if step_move else nominal
            summary["vibrations"].append(summarize_vibration(robot, signals, nominal, vib["parameters"],
                                                             vib["start_time"]))
        summary["bound_failures"] = check_bounds(summary, scenario.bounds)
        summary["report_dir"] = _write_report(record.mcap_path, out / "report")
        if summary["bound_failures"]:
            status = 1
    (out / "summary.json").write_text(json.dumps(to_jsonable(summary), indent=2))
    if args.json:
        print(json.dumps(to_jsonable(summary), indent=2))
    else:
        _print_summary(summary, scenario.bounds)
    return status


def _pair_vibrations(record):
    """Each vibration with the last move that preceded it (its nominal pose)."""
    pairs = []
    for vib in record.vibrations:
        before = [m for m in record.moves if m["time"] <= vib["start_time"]]
        pairs.append((before[-1] if before else None, vib))
    return pairs


def _write_report(mcap_path: Path, report_dir: Path) -> str | None:
    """Run ``stewart-vibration report`` on the MCAP; returns the directory, or None if it failed."""
    result = subprocess.run([sys.executable, "-m", "stewart_vibration", "report", str(mcap_path), "--out",
                             str(report_dir)], capture_output=True, text=True, timeout=600)
    if result.returncode != 0:
        _log(f"report failed: {result.stderr.strip()[-500:]}")
        return None
    return str(report_dir)


def _print_ui_help(namespace: str, domain: int) -> None:
    ns = namespace.rstrip("/")
    print(f"""
Nodes are running (Ctrl-C stops them and finishes the MCAP). In another shell:
  export ROS_DOMAIN_ID={domain} ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
  ros2 topic pub --once {ns}/platform/target_pose geometry_msgs/msg/PoseStamped \\
    "{{header: {{frame_id: base}}, pose: {{position: {{z: 0.165}}, orientation: {{w: 1.0}}}}}}"
  ros2 param set {ns}/vibration_planner acceleration_g 0.3
  ros2 service call {ns}/vibration_planner/start std_srvs/srv/Trigger
  ros2 service call {ns}/vibration_planner/stop std_srvs/srv/Trigger
  ros2 service call {ns}/hardware_emulator/emergency_stop std_srvs/srv/Trigger
""", flush=True)


def _print_summary(summary: dict, bounds: dict) -> None:
    print("\n=== run summary ===")
    print(f"scenario: {summary['scenario']}")
    for move in summary["moves"]:
        print(f"move to {move['name']}: ground-truth error {move['pose_error_m'] * 1e6:.3f} um, "
              f"{move['pose_error_deg']:.5f} deg (bounds {bounds['pose_error_m'] * 1e6:g} um, "
              f"{bounds['pose_error_deg']:g} deg)")
    for i, vib in enumerate(summary["vibrations"], start=1):
        print(f"vibration {i}: {vib['frequency_hz']:g} Hz, planned {vib['planned_amplitude_m'] * 1e6:.2f} um along "
              f"{np.round(vib['planned_direction'], 4).tolist()} (base frame)")
        print(f"  platform (ground truth): amplitude {vib['measured_amplitude_m'] * 1e6:.3f} um "
              f"(error {vib['amplitude_error'] * 100:.3f} %), direction error {vib['direction_error_deg']:.4f} deg, "
              f"off-axis ratio {vib['off_axis_ratio']:.2e}")
        print("  leg   amplitude_um  expected_um  phase_deg  expected_deg  freq_Hz")
        for k in range(6):
            amp, expected = vib["leg_amplitude_m"][k] * 1e6, vib["leg_amplitude_expected_m"][k] * 1e6
            print(f"  {k + 1}     {amp:10.3f}  {expected:10.3f}"
                  f"  {vib['leg_phase_deg'][k]:9.3f}  {vib['leg_phase_expected_deg'][k]:12.3f}"
                  f"  {vib['leg_frequency_hz'][k]:.5f}")
        if vib["force"] is not None:
            f = vib["force"]
            print(f"  leg forces, model vs emulator: RMS error {np.round(f['rms_error_n'], 4).tolist()} N; "
                  f"worst leg {f['worst_leg_relative'] * 100:.3f} % of the force amplitude")
    print(f"MCAP: {summary['mcap']}")
    print(f"report: {summary.get('report_dir')}")
    if summary.get("failure"):
        print(f"FAILED: {summary['failure']}")
    elif summary.get("interrupted"):
        print("INTERRUPTED")
    elif summary.get("bound_failures"):
        print("MISSED BOUNDS:\n  " + "\n  ".join(summary["bound_failures"]))
    else:
        print("all figures within their bounds")

