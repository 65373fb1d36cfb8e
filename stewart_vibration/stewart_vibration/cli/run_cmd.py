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
from pathlib import Path

from ..dynamics.tissue_config import load_tissue
from ..emulation.plant import load_plant_option
from ..errors import InvalidInputError
from ..kinematics.robot_config import load_drawing, load_robot
from ..runtime.interrupts import INTERRUPTS
from ..runtime.processes import DOMAIN_RANGE, claim_ros_domain
from ..runtime.run_folders import new_run_folder, reserve_file, write_reserved
from ..runtime.run_options import VIBRATION_CONTROL
from ..runtime.scenario import load_scenario, resolve_tissue_path
from ..runtime.sim_clock import REAL_TIME_FACTOR_MAX, REAL_TIME_FACTOR_MIN
from ..runtime.suite import DEFAULT_NAMESPACE, SUITE_NODES
from ..safe_yaml import load_yaml
from ..vibration.unit_identification import load_identification
from .arguments import nonnegative_float, positive_float, ros_namespace
from .output import to_jsonable
from .run_analysis import summarize
from .run_console import log, print_summary, print_ui_help, print_views

SUMMARY_RESERVE_BYTES = 1 << 20  # summary.json of a 60 s run: ~30 kB; a recording's gaps are listed up to 100


def register(subparsers) -> None:
    """Add the ``run`` subcommand (the main job) to ``subparsers``."""
    cmd = subparsers.add_parser("run", help="bring up the node suite in emulation and run a scenario (main job)")
    cmd.add_argument("--scenario", help="scenario YAML (default: config/scenario_paper.yaml)")
    cmd.add_argument("--tissue", help="soft-tissue YAML the emulator applies and kinematics checks against (e.g. "
                     "tissue.yaml, looked up in config/ too; 'none' = no tissue); default: the scenario's `tissue:`")
    cmd.add_argument("--duration", type=positive_float,
                     help="override every vibration's duration (s, incl. ramps)")
    cmd.add_argument("--real-time-factor", type=real_time_factor, default=1.0,
                     help=f"sim seconds per wall second, {REAL_TIME_FACTOR_MIN:g} to {REAL_TIME_FACTOR_MAX:g} (default "
                          "1; 0 = the emulator as fast as it can: on 2 cores the other nodes keep up to about 2x, "
                          "beyond that the run reports lost samples)")
    cmd.add_argument("--lockstep", action="store_true",
                     help="the emulator waits while the pose or wrench estimates lag (its lockstep parameter): on a "
                          "machine too slow for the suite at real time, sim time slows down instead of the force "
                          "guard pausing moves for late estimates")
    cmd.add_argument("--plant", default="ideal",
                     help="the emulated robot: 'ideal' (the drawing, config/robot.yaml; default), 'realistic' "
                          "(config/plant_realistic.yaml: resonant vibration units, strut servos on their encoders, "
                          "geometry errors, sensor noise) or a plant YAML (looked up in config/ too)")
    cmd.add_argument("--plant-seed", type=plant_seed, default=None,
                     help="seed of the plant's drawn errors (a whole number >= 0; default: the plant file's)")
    cmd.add_argument("--vibration-control", choices=VIBRATION_CONTROL, default=VIBRATION_CONTROL[0],
                     help="closed_loop (default): before each vibration the planner identifies the vibration units "
                          "at its pose and frequency (~6 s), plans the leg demands with that identification's "
                          "feed-forward and corrects them from the platform IMU; feedforward: the same without the "
                          "correction; off: the drawing's decomposition, uncompensated")
    cmd.add_argument("--identification", default=None, metavar="FILE",
                     help="a vibration-unit identification (a file the identify_vibration_units action or an earlier "
                          "run wrote) reused for a vibration where it holds (its pose within 2 mm / 1 deg, its "
                          "frequencies); elsewhere the run identifies. A closed loop that has to move the demands "
                          "more than 20 %% from its feed-forward marks it stale: the run identifies again (and runs "
                          "the vibration again on the fresh file when the loop could not hold it on the stale one)")
    cmd.add_argument("--params-file", default=None,
                     help="a ROS 2 parameter file applied to the nodes after the suite's own "
                          "(config/suite_params.yaml): your hardware's data-sheet figures, e.g. kinematics' and the "
                          "planner's unit_sensor_latency_s, kinematics' tracker_* (keys /**/<node name>)")
    cmd.add_argument("--out", default=None,
                     help="output directory (MCAP, logs, report); default: a new runs/run_<stamp>/, with "
                          "runs/latest pointing at it")
    cmd.add_argument("--domain-id", type=domain_id, default=None,
                     help="ROS_DOMAIN_ID, 0..101 (default: $ROS_DOMAIN_ID if set, else a free one)")
    cmd.add_argument("--namespace", type=ros_namespace, default=DEFAULT_NAMESPACE,
                     help=f"namespace of every node (default {DEFAULT_NAMESPACE})")
    cmd.add_argument("--keep-running", action="store_true",
                     help="after the scenario keep the nodes up for a UI until Ctrl-C (then report what ran)")
    cmd.add_argument("--respawn", type=node_names,
                     default=",".join(n.name for n in SUITE_NODES if n.name != "hardware_emulator"),
                     help="with --keep-running: nodes restarted when they exit (comma-separated; default: all "
                          "but hardware_emulator, whose restart would move the robot home)")
    cmd.add_argument("--foxglove", action="store_true",
                     help="also start the Foxglove bridge (WebSocket on 127.0.0.1:8765 by default)")
    cmd.add_argument("--ui", action="store_true",
                     help="also start the planning UI (a browser page on 127.0.0.1; its URL with the access "
                          "token is printed)")
    cmd.add_argument("--json", action="store_true", help="print the summary as JSON")
    cmd.set_defaults(func=run)


DOMAIN_ID_MAX = DOMAIN_RANGE.stop - 1


def domain_id(text: str) -> int:
    """ROS domain 0..101 (higher ids put Fast DDS ports in the ephemeral range)."""
    value = nonnegative_float(text)
    if value != int(value) or value > DOMAIN_ID_MAX:
        raise argparse.ArgumentTypeError(f"must be a whole number in 0..{DOMAIN_ID_MAX}, got {text}")
    return int(value)


def real_time_factor(text: str) -> float:
    """0 (as fast as possible) or a factor in [REAL_TIME_FACTOR_MIN, REAL_TIME_FACTOR_MAX]."""
    value = nonnegative_float(text)
    if value != 0 and not REAL_TIME_FACTOR_MIN <= value <= REAL_TIME_FACTOR_MAX:
        raise argparse.ArgumentTypeError(f"must be 0 (as fast as possible) or in [{REAL_TIME_FACTOR_MIN:g}, "
                                         f"{REAL_TIME_FACTOR_MAX:g}], got {text}")
    return value


def plant_seed(text: str) -> int:
    """A plant seed: a whole number in 0..2^31 - 1."""
    value = nonnegative_float(text)
    if value != int(value) or value > 2**31 - 1:
        raise argparse.ArgumentTypeError(f"must be a whole number in 0..{2**31 - 1}, got {text}")
    return int(value)


def node_names(text: str) -> str:
    """Comma-separated names of suite nodes (--respawn); each must be one of SUITE_NODES."""
    names = {n for n in text.split(",") if n}
    unknown = names - {n.name for n in SUITE_NODES}
    if unknown:
        raise argparse.ArgumentTypeError(f"unknown node(s) {sorted(unknown)}; known: {[n.name for n in SUITE_NODES]}")
    return text


def _output_folder(given: str | None) -> Path:
    """The run's output folder, created now (a path that cannot be a folder, or a folder that already holds a
    run, fails before any node starts): ``given``, or a new runs/run_<stamp>/."""
    if given is None:
        return new_run_folder("runs")
    out = Path(given).expanduser()
    if out.exists() and not out.is_dir():
        raise InvalidInputError(f"--out {given}: exists and is not a folder")
    earlier = sorted(p.name for p in out.glob("*.mcap")) if out.is_dir() else []
    if earlier or (out / "metadata.yaml").exists():
        # the summary reads every MCAP of the folder as one run's files: another run's would be judged with it
        raise InvalidInputError(f"--out {given}: already holds a run ({', '.join(earlier) or 'metadata.yaml'}); "
                                "give a new or empty folder")
    out.mkdir(parents=True, exist_ok=True)  # OSError (permissions, a file on the way): one line from main
    return out


def _given_domain(given: int | None) -> tuple[int | None, str]:
    """(domain or None, where it came from): --domain-id, else $ROS_DOMAIN_ID (checked), else None."""
    if given is not None:
        return given, "--domain-id"
    env = os.environ.get("ROS_DOMAIN_ID", "").strip()
    if not env:
        return None, "a free domain (ROS_DOMAIN_ID was not set)"
    try:
        return domain_id(env), "$ROS_DOMAIN_ID"
    except argparse.ArgumentTypeError as exc:
        raise InvalidInputError(f"$ROS_DOMAIN_ID {env!r}: {exc}") from None


def _domain_and_lock(given: int | None):
    """(domain, lock or None): ``given``, or a free domain locked for the run (``claim_ros_domain``)."""
    return (given, None) if given is not None else claim_ros_domain()


def run(args) -> int:
    """``run``: bring up the node suite, run the scenario, record the MCAP, report and print the summary.

    Writes summary.json to the run folder. Returns 0 (all done, within bounds), 1 (a figure missed its
    bound), 2 (a step failed or a problem) or 130 (interrupted). Raises, before anything starts, ConfigError
    (a bad robot, scenario or tissue file), InvalidInputError (a bad $ROS_DOMAIN_ID, an --out that is a file)
    and OSError (an --out that cannot be made). With --robot every node, the scenario's checks, the summary
    and the report use that robot.
    """
    robot = load_robot(args.robot)
    robot_config = str(Path(robot.source).resolve()) if args.robot else None  # every node reads this robot
    scenario = load_scenario(robot, args.scenario, args.duration)
    tissue = scenario.tissue
    if args.tissue is not None:
        tissue = None if args.tissue.lower() in ("", "none") else resolve_tissue_path(args.tissue, Path.cwd())
        if tissue is not None:
            load_tissue(tissue, robot)
    if args.params_file:  # a parameter file that cannot be read safely is refused before anything starts
        load_yaml(Path(args.params_file), "node parameter file")
    if args.identification:  # so is an identification that does not load
        load_identification(Path(args.identification))
    # refused here, before anything starts; the emulated robot is built from the drawing of the robot file
    plant = load_plant_option(args.plant, load_drawing(args.robot), args.plant_seed)
    # the ideal plant is the drawing: the emulator runs today's model without a plant file
    built = plant if plant is not None and plant.kind != "ideal" else None
    plant_config = str(Path(built.source).resolve()) if built is not None else None
    plant_summary = {"kind": built.kind, "seed": built.seed, "config": plant_config} if built is not None else \
        {"kind": "ideal", "seed": None, "config": None}
    respawn = {n for n in args.respawn.split(",") if n}
    given, source = _given_domain(args.domain_id)
    out = _output_folder(args.out)
    domain, _lock = _domain_and_lock(given)
    try:  # the summary's room on disk, taken before the recording can fill it
        reserve_file(out / "summary.json", SUMMARY_RESERVE_BYTES)
    except OSError as exc:
        log(f"cannot reserve room for summary.json in {out}: {exc}")
    extra = tuple(key for key, wanted in (("foxglove", args.foxglove), ("ui", args.ui)) if wanted)
    from ..nodes.suite_runner import RunOptions, StepFailed, SuiteRunner  # rclpy only once the inputs are good

    options = RunOptions(namespace=args.namespace, domain_id=domain, real_time_factor=args.real_time_factor,
                         lockstep=args.lockstep, out_dir=out, progress=log, extra_nodes=extra, tissue_config=tissue,
                         robot_config=robot_config, plant_config=plant_config,
                         plant_seed=built.seed if built is not None else None,
                         vibration_control=args.vibration_control,
                         hardware_params_file=Path(args.params_file) if args.params_file else None,
                         identification_file=Path(args.identification).resolve() if args.identification else None)
    INTERRUPTS.install()  # SIGINT and SIGTERM: KeyboardInterrupt, never inside rclpy's C++
    runner = SuiteRunner(options)
    status, failure = 0, None
    lockstep = " (lockstep)" if args.lockstep else ""
    log(f"scenario '{scenario.name}' ({scenario.source}); ROS_DOMAIN_ID={domain} ({source}), namespace "
         f"{args.namespace}, real-time factor {args.real_time_factor or 'max'}{lockstep}; output {out.resolve()}; "
         f"robot {robot.source}; soft tissue: {tissue or 'none'}; plant: {plant_summary['kind']}"
         f"{f' seed {built.seed} ({plant_config})' if built is not None else ''}")
    log(f"to attach ros2 tools or a viewer from another shell: export ROS_DOMAIN_ID={domain} "
         "ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST")
    try:
        runner.start()
        runner.wait_ready()
        print_views(runner, extra)
        runner.run(scenario)
        if args.keep_running:
            print_ui_help(args.namespace, domain)
            runner.supervise(respawn)
    except KeyboardInterrupt:
        runner.record.interrupted = True
        status = 130
        log("interrupted: stopping the recorder and every node")
    except StepFailed as exc:
        status, failure = 2, str(exc)
        log(f"FAILED: {exc}")
        for line in runner.recent_problems():
            log(f"  {line}")
        try:
            runner.bring_to_rest()
        except KeyboardInterrupt:
            runner.record.interrupted = True
    finally:
        runner.stop()
    record = runner.record
    log(f"all nodes stopped; MCAP: {record.mcap_path}")
    summary = {"scenario": scenario.name, "mcap": str(record.mcap_path) if record.mcap_path else None,
               "moves": record.moves, "vibrations": [], "failure": failure, "interrupted": record.interrupted,
               "problems": list(record.failures), "recorder": record.recorder_stats,
               "restarts": record.restarts, "ros_domain_id": domain, "tissue_config": tissue,
               "plant": plant_summary, "vibration_control": args.vibration_control,
               "identification_file": str(Path(args.identification).resolve()) if args.identification else None,
               "identifications": record.identifications, "guard_stops": record.guard_stops}
    if not list(out.glob("*.mcap")):
        log("no MCAP was written")
        summary["problems"].append("no MCAP was written")
    else:
        summarize(robot, record, summary, scenario, out, robot_config)
    summary["problems"] = list(dict.fromkeys(summary["problems"]))  # one line per problem, however it was seen
    if summary["problems"] and status == 0:
        status = 2
    if summary.get("bound_failures") and status == 0:
        status = 1
    try:
        write_reserved(out / "summary.json", json.dumps(to_jsonable(summary), indent=2))
    except OSError as exc:  # a disk full beyond the summary's reserve: the summary is still printed
        summary["problems"].append(f"summary.json could not be written: {exc}")
        status = status or 2
    if args.json:
        print(json.dumps(to_jsonable(summary), indent=2))
    else:
        print_summary(summary, scenario.bounds)
    return status
