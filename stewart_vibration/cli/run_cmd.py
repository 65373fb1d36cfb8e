"""``stewart-vibration run``: the main job. Brings up the whole node suite (each node its own
process, sim time, own ROS domain), runs a scenario, logs an MCAP, writes the report and prints
a summary checked against the scenario's bounds.

Exit codes: 0 all steps done and every figure within its bound; 1 a figure missed its bound;
2 a step failed (or bad input); 130 interrupted (Ctrl-C / SIGTERM).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from ..dynamics.tissue import load_tissue
from ..robot import load_robot
from ..runtime.interrupts import INTERRUPTS
from ..runtime.processes import claim_ros_domain
from ..runtime.run_folders import new_run_folder
from ..runtime.scenario import load_scenario, resolve_tissue_path
from ..runtime.suite import OPTIONAL_NODES, SUITE_NODES
from .arguments import nonnegative_float, positive_float
from .output import to_jsonable


def register(subparsers) -> None:
    """Add the ``run`` subcommand (the main job) to ``subparsers``."""
    cmd = subparsers.add_parser("run", help="bring up the node suite in emulation and run a scenario (main job)")
    cmd.add_argument("--scenario", help="scenario YAML (default: config/scenario_paper.yaml)")
    cmd.add_argument("--tissue", help="soft-tissue YAML the emulator applies and kinematics checks against (e.g. "
                     "tissue.yaml, looked up in config/ too; 'none' = no tissue); default: the scenario's `tissue:`")
    cmd.add_argument("--duration", type=positive_float,
                     help="override every vibration's duration (s, incl. ramps)")
    cmd.add_argument("--real-time-factor", type=nonnegative_float, default=1.0,
                     help="sim seconds per wall second (default 1; 0 = the emulator as fast as it can: on 2 cores "
                          "the other nodes keep up to about 2x, beyond that the run reports lost samples)")
    cmd.add_argument("--out", default=None,
                     help="output directory (MCAP, logs, report); default: a new runs/run_<stamp>/, with "
                          "runs/latest pointing at it")
    cmd.add_argument("--domain-id", type=domain_id, default=None,
                     help="ROS_DOMAIN_ID, 0..101 (default: $ROS_DOMAIN_ID if set, else a free one)")
    cmd.add_argument("--namespace", default="/stewart", help="namespace of every node (default /stewart)")
    cmd.add_argument("--keep-running", action="store_true",
                     help="after the scenario keep the nodes up for a UI until Ctrl-C (then report what ran)")
    cmd.add_argument("--respawn", default=",".join(n.name for n in SUITE_NODES if n.name != "hardware_emulator"),
                     help="with --keep-running: nodes restarted when they exit (comma-separated; default: all "
                          "but hardware_emulator, whose restart would move the robot home)")
    cmd.add_argument("--foxglove", action="store_true",
                     help="also start the Foxglove bridge (WebSocket on 127.0.0.1:8765 by default)")
    cmd.add_argument("--ui", action="store_true",
                     help="also start the planning UI (a browser page on 127.0.0.1; its URL with the access "
                          "token is printed)")
    cmd.add_argument("--json", action="store_true", help="print the summary as JSON")
    cmd.set_defaults(func=run)


def domain_id(text: str) -> int:
    """ROS domain 0..101 (higher ids put Fast DDS ports in the ephemeral range)."""
    value = nonnegative_float(text)
    if value != int(value) or value > 101:
        raise argparse.ArgumentTypeError(f"must be a whole number in 0..101, got {text}")
    return int(value)


def _log(message: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {message}", flush=True)


def _choose_domain(given: int | None):
    """(domain, lock or None, where it came from): --domain-id, $ROS_DOMAIN_ID, or a free one (locked)."""
    if given is not None:
        return given, None, "--domain-id"
    env = os.environ.get("ROS_DOMAIN_ID", "").strip()
    if env:
        return int(env), None, "$ROS_DOMAIN_ID"
    domain, lock = claim_ros_domain()
    return domain, lock, "a free domain (ROS_DOMAIN_ID was not set)"


def run(args) -> int:
    """``run``: bring up the node suite, run the scenario, record the MCAP, report and print the summary.

    Writes summary.json to the run folder. Returns 0 (all done, within bounds), 1 (a figure missed its
    bound), 2 (a step failed, a problem, or an unknown --respawn node) or 130 (interrupted). Raises
    ConfigError (a bad robot, scenario or tissue file) before anything starts.
    """
    from ..nodes.suite_runner import RunOptions, StepFailed, SuiteRunner  # rclpy only here, lazily

    robot = load_robot(args.robot)
    scenario = load_scenario(robot, args.scenario, args.duration)
    tissue = scenario.tissue
    if args.tissue is not None:
        tissue = None if args.tissue.lower() in ("", "none") else resolve_tissue_path(args.tissue, Path.cwd())
        if tissue is not None:
            load_tissue(tissue, robot)
    respawn = {n for n in args.respawn.split(",") if n}
    unknown = respawn - {n.name for n in SUITE_NODES}
    if unknown:
        _log(f"--respawn: unknown node(s) {sorted(unknown)}; known: {[n.name for n in SUITE_NODES]}")
        return 2
    out = Path(args.out) if args.out else new_run_folder("runs")
    domain, _lock, source = _choose_domain(args.domain_id)
    extra = tuple(key for key, wanted in (("foxglove", args.foxglove), ("ui", args.ui)) if wanted)
    options = RunOptions(namespace=args.namespace, domain_id=domain, real_time_factor=args.real_time_factor,
                         out_dir=out, progress=_log, extra_nodes=extra, tissue_config=tissue)
    INTERRUPTS.install()  # SIGINT and SIGTERM: KeyboardInterrupt, never inside rclpy's C++
    runner = SuiteRunner(options)
    status, failure = 0, None
    _log(f"scenario '{scenario.name}' ({scenario.source}); ROS_DOMAIN_ID={domain} ({source}), namespace "
         f"{args.namespace}, real-time factor {args.real_time_factor or 'max'}; output {out.resolve()}; "
         f"soft tissue: {tissue or 'none'}")
    _log(f"to attach ros2 tools or a viewer from another shell: export ROS_DOMAIN_ID={domain} "
         "ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST")
    try:
        runner.start()
        runner.wait_ready()
        _print_views(runner, extra)
        runner.run(scenario)
        if args.keep_running:
            _print_ui_help(args.namespace, domain)
            runner.supervise(respawn)
    except KeyboardInterrupt:
        runner.record.interrupted = True
        status = 130
        _log("interrupted: stopping the recorder and every node")
    except StepFailed as exc:
        status, failure = 2, str(exc)
        _log(f"FAILED: {exc}")
        for line in runner.recent_problems():
            _log(f"  {line}")
    finally:
        runner.stop()
    record = runner.record
    _log(f"all nodes stopped; MCAP: {record.mcap_path}")
    summary = {"scenario": scenario.name, "mcap": str(record.mcap_path) if record.mcap_path else None,
               "moves": record.moves, "vibrations": [], "failure": failure, "interrupted": record.interrupted,
               "problems": list(record.failures), "recorder": record.recorder_stats,
               "restarts": record.restarts, "ros_domain_id": domain, "tissue_config": tissue,
               "guard_stops": record.guard_stops}
    if record.mcap_path is None:
        _log("no MCAP was written")
        summary["problems"].append("no MCAP was written")
    else:
        _summarize(robot, record, summary, scenario, out)
    if summary["problems"] and status == 0:
        status = 2
    if summary.get("bound_failures") and status == 0:
        status = 1
    (out / "summary.json").write_text(json.dumps(to_jsonable(summary), indent=2))
    if args.json:
        print(json.dumps(to_jsonable(summary), indent=2))
    else:
        _print_summary(summary, scenario.bounds)
    return status


def _summarize(robot, record, summary: dict, scenario, out: Path) -> None:
    """Analyse what ran (also after a failure or an interruption): every vibration that started, the
    streams, the bounds; write the report. Problems change the verdict."""
    from ..analysis.run_summary import check_bounds, load_signals, stream_summary, summarize_tissue, summarize_vibration

    try:
        signals = load_signals(record.mcap_path)
    except Exception as exc:  # noqa: BLE001 - an unreadable log is a failed run, said in one line
        summary["problems"].append(f"the MCAP cannot be analysed: {type(exc).__name__}: {exc}")
        return
    nominal = robot.home_pose
    for step_move, vib in _pair_vibrations(record):
        nominal = np.asarray(step_move["target"]) if step_move else nominal
        try:
            result = summarize_vibration(robot, signals, nominal, vib["parameters"], vib["start_time"])
        except Exception as exc:  # noqa: BLE001 - e.g. interrupted before it vibrated
            summary["problems"].append(f"vibration starting at {vib['start_time']:.3f} s cannot be analysed: "
                                       f"{type(exc).__name__}: {exc}")
            continue
        result["failure"] = vib.get("failure")
        summary["vibrations"].append(result)
    summary["tissue"] = summarize_tissue(signals, [(v["t0"], float(v["parameters"]["duration_s"]))
                                                   for v in record.vibrations if "t0" in v])
    summary["streams"] = stream_summary(signals)
    summary["bound_failures"] = check_bounds(summary, scenario.bounds)
    summary["report_dir"] = _write_report(record.mcap_path, out / "report")
    if summary["report_dir"] is None:
        summary["problems"].append("the report could not be written (see the log above)")


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


def _print_views(runner, extra) -> None:
    """The addresses the optional nodes print in their logs (lines with 'http://' or 'ws://')."""
    for key in extra:
        node = OPTIONAL_NODES[key].name
        deadline = time.monotonic() + 20
        lines: list[str] = []
        while time.monotonic() < deadline and not lines:
            lines = runner.log_lines(node, "://")
            time.sleep(0.2)
        for line in lines[-2:]:
            _log(f"{node}: {line.split('] ')[-1]}")
        if not lines:
            _log(f"{node}: no address in its log yet (see {runner.record.log_dir}/{node}.log)")


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
        print(f"  active (>= half amplitude) {vib['active_duration_s']:.3f} s of the planned "
              f"{vib['planned_active_duration_s']:.3f} s")
        if vib.get("failure"):
            print(f"  this vibration failed: {vib['failure']}")
    from ..analysis.run_summary import tissue_lines

    for line in tissue_lines(summary):
        print(line)
    streams = summary.get("streams")
    if streams:
        counts = ", ".join(f"{t} {row['count']} ({row['ratio'] * 100:.2f} %)" for t, row in streams["topics"].items())
        print(f"samples: {counts}")
        for node, row in streams["nodes"].items():
            print(f"  {node}: {row['received']} states received, {row['lost']} lost, lag p50 {row['lag_p50_ms']:.1f} "
                  f"ms / p99 {row['lag_p99_ms']:.1f} ms")
    if summary.get("recorder"):
        r = summary["recorder"]
        print(f"recorder: {r.get('written')} messages written, {r.get('dropped')} dropped")
    for name, code in summary.get("restarts", []):
        print(f"restarted: {name} (exit code {code})")
    print(f"MCAP: {summary['mcap']}")
    print(f"report: {summary.get('report_dir')}")
    for problem in summary.get("problems", []):
        print(f"PROBLEM: {problem}")
    if summary.get("failure"):
        print(f"FAILED: {summary['failure']}")
    elif summary.get("interrupted"):
        print("INTERRUPTED (the summary above covers what ran)")
    elif summary.get("problems"):
        print("FAILED: see the problems above")
    elif summary.get("bound_failures"):
        print("MISSED BOUNDS:\n  " + "\n  ".join(summary["bound_failures"]))
    else:
        print("all figures within their bounds")

