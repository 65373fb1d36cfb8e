#!/usr/bin/env python3
"""Record the force guard's events of a real guarded move into a small fixture for test/test_force_guard.py.

    .venv/bin/python tools/record_guard_events.py [--out test/data/guard_trip_events.npz] [--run RUN_FOLDER]

Without --run it runs the tissue scenario (``stewart-vibration run --scenario config/scenario_tissue.yaml
--lockstep --duration 1.2``, as test/test_tissue_scenario.py does: the whole node suite over DDS, about a minute,
on $ROS_DOMAIN_ID or the --domain-id given) into a temporary folder; with --run it reads a run folder that such a
run wrote. From the run's MCAP it keeps only the scenario's guarded move (its ``guarded_move_to``: a 12 mm
distraction the guard stops near its 200 N limit), from shortly before the move was sent to a little after the
guard's final status, and writes a compressed NPZ:

- ``states_*``: legs/joint_states (stamp s, leg_1..6 strut lengths m), ``wrench_*``:
  platform/external_wrench_estimate (stamp s, [force N, torque N m]), ``clock_*``: /clock (s), ``pose_*``: the
  stamps of the node's own platform/pose_estimate (one per state it has read: when it read which); each with the
  recorder's log time (``*_log_ns``) and its place in the recorder's log-time order (``*_seq``: log times tie
  within one /clock period, the place keeps the order the recorder received them in);
- ``move_*``: the move's leg trajectory as sent (stamp, point times s, positions m, log time and place),
  ``stop_*``: the one-point stop trajectory sent after the trip, likewise;
- ``status_*``: every kinematics/guard_status the node published over the window (state, limits, trip time,
  trip and predicted force and moment, peak, stop duration and progress, the tripped goal pose, log time);
- ``start_pose``, ``start_pose_stamp``: the newest platform/pose_estimate before the move was sent;
- ``param_names`` / ``param_values``: the kinematics node's guard and batching parameters of the run (its
  parameter table's defaults with config/suite_params.yaml over them, as the runner starts the node);
- ``source``: which run made it (scenario, plant and seed, lockstep, the MCAP's name, the commit).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from stewart_vibration.analysis.run_streams import topic_key
from stewart_vibration.install import default_config_dir
from stewart_vibration.mcap_log.reader import open_run
from stewart_vibration.messages import cdr
from stewart_vibration.messages.joint_states import decode_joint_states_dropping_malformed
from stewart_vibration.messages.joint_trajectory import decode_joint_trajectory
from stewart_vibration.messages.stamped import pose_from_cdr, wrenches_from_cdr
from stewart_vibration.messages.status_values import guard_status_from_cdr
from stewart_vibration.motion.force_guard import WATCH_AFTER_S
from stewart_vibration.motion.guard_parameters import GUARD_PARAMETERS
from stewart_vibration.parameters.tables import KINEMATICS
from stewart_vibration.robot import LEG_NAMES
from stewart_vibration.safe_yaml import load_yaml

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = "scenario_tissue.yaml"
RUN_OPTIONS = ("--lockstep", "--duration", "1.2")  # as test/test_tissue_scenario.py runs it
BEFORE_S = 0.3  # kept before the move was sent (s of log time): the baseline estimates and the start's states
AFTER_S = 0.3  # kept after the guard's status with the final peak (s of log time)
TOPICS = ("legs/joint_states", "platform/external_wrench_estimate", "/clock", "legs/joint_trajectory",
          "kinematics/guard_status", "platform/pose_estimate")
PARAMETERS = GUARD_PARAMETERS + ("batch_period_s", "batch_size")
STATUS_FIELDS = ("trip_time_s", "trip_force_n", "trip_moment_nm", "predicted_force_n", "predicted_moment_nm",
                 "peak_force_n", "peak_moment_nm", "stop_duration_s", "stop_progress", "force_limit_n",
                 "moment_limit_nm")


def run_scenario(out: Path, domain_id: int | None) -> None:
    """The tissue scenario, run for real into ``out`` (exit code 0 required)."""
    command = [sys.executable, "-m", "stewart_vibration", "run", "--scenario", str(default_config_dir() / SCENARIO),
               "--out", str(out), *RUN_OPTIONS]
    if domain_id is not None:
        command += ["--domain-id", str(domain_id)]
    done = subprocess.run(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=600)
    if done.returncode != 0:
        raise SystemExit(f"the tissue scenario failed (exit {done.returncode}):\n{done.stdout[-3000:]}")


def node_parameters() -> dict[str, float]:
    """The kinematics node's PARAMETERS as the runner starts it: table defaults, config/suite_params.yaml over."""
    values: dict[str, Any] = {p.name: p.default for p in KINEMATICS if p.name in PARAMETERS}
    params = load_yaml(default_config_dir() / "suite_params.yaml", "suite parameter file")
    values.update({k: v for k, v in params.get("/**/kinematics", {}).get("ros__parameters", {}).items()
                   if k in PARAMETERS})
    return {name: float(values[name]) for name in PARAMETERS}


def recorded(run_dir: Path) -> tuple[list, str]:
    """The run's messages of TOPICS in the recorder's log-time order (ties in the order it received them):
    [(place, key, raw message)], and the MCAP's name."""
    run = open_run(run_dir)
    names = sorted({t.topic for t in run.topics() if topic_key(t.topic, TOPICS) is not None})
    messages = [(i, topic_key(m.topic, TOPICS), m) for i, m in enumerate(run.messages(names))]
    return messages, Path(getattr(run, "path", run_dir)).name


def guarded_move(messages: list) -> tuple[tuple, tuple, list]:
    """(move, stop, statuses): the move's and the stop's (place, raw, decoded trajectory), every guard status
    [(raw, GuardStatus)]. The move is the last multi-point trajectory sent before the first force trip was
    published, the stop the one-point trajectory sent after it."""
    statuses = [(m, guard_status_from_cdr(m.data)) for _i, key, m in messages if key == "kinematics/guard_status"]
    trip = next((m for m, s in statuses if s.tripped and s.trip_limit == "force"), None)
    if trip is None:
        raise SystemExit("no force trip in this run's kinematics/guard_status")
    sent = [(i, m, decode_joint_trajectory(m.data)) for i, key, m in messages if key == "legs/joint_trajectory"]
    move = [row for row in sent if len(row[2].times) > 1 and row[1].log_time <= trip.log_time][-1]
    stop = next(row for row in sent if len(row[2].times) == 1 and row[0] > move[0])
    return move, stop, statuses


def extract(run_dir: Path, out: Path, source: dict) -> dict:
    """Write the guarded move's events of the run in ``run_dir`` to ``out``; returns what was written."""
    messages, mcap_name = recorded(run_dir)
    (move_at, move_raw, move), (stop_at, stop_raw, stop), statuses = guarded_move(messages)
    final = [m for m, s in statuses if s.tripped and m.log_time > stop_raw.log_time]
    last = final[0].log_time if final else stop_raw.log_time + int((stop.times[-1] + WATCH_AFTER_S) * 1e9)
    first_ns, last_ns = move_raw.log_time - int(BEFORE_S * 1e9), last + int(AFTER_S * 1e9)
    window = [(i, key, m) for i, key, m in messages if first_ns <= m.log_time <= last_ns]
    data: dict = {}
    for key, name in (("legs/joint_states", "states"), ("platform/external_wrench_estimate", "wrench"),
                      ("/clock", "clock"), ("platform/pose_estimate", "pose")):
        rows = [(i, m) for i, k, m in window if k == key]
        data[f"{name}_seq"] = np.array([i for i, _m in rows], np.int64)
        data[f"{name}_log_ns"] = np.array([m.log_time for _i, m in rows], np.int64)
        raw = [m.data for _i, m in rows]
        if name == "states":
            (batch,), kept = decode_joint_states_dropping_malformed(raw)  # one layout: the emulator's
            data["states_stamp"], data["states_legs"] = batch.stamps, batch.position[:, [batch.names.index(n)
                                                                                         for n in LEG_NAMES]]
        elif name == "wrench":
            decoded = wrenches_from_cdr(raw, "external wrench estimate")
            kept = decoded.kept
            data["wrench_stamp"], data["wrench_values"] = decoded.stamps, decoded.values
        else:
            data[f"{name}_stamp"] = np.array([cdr.header_stamp_ns(d) for d in raw], np.int64) / 1e9
            kept = np.arange(len(raw))
        if len(kept) != len(rows):
            raise SystemExit(f"{len(rows) - len(kept)} malformed {key} message(s) in the window")
    for name, at, raw, trajectory in (("move", move_at, move_raw, move), ("stop", stop_at, stop_raw, stop)):
        data.update({f"{name}_stamp": trajectory.stamp, f"{name}_times": trajectory.times,
                     f"{name}_positions": trajectory.positions, f"{name}_log_ns": raw.log_time, f"{name}_seq": at})
    window_statuses = [(m, s) for m, s in statuses if first_ns <= m.log_time <= last_ns]
    data["status_log_ns"] = np.array([m.log_time for m, _s in window_statuses], np.int64)
    data["status_state"] = np.array([s.state for _m, s in window_statuses])
    data["status_trip_limit"] = np.array([s.trip_limit for _m, s in window_statuses])
    for field in STATUS_FIELDS:
        data[f"status_{field}"] = np.array([getattr(s, field) for _m, s in window_statuses])
    data["status_tripped_goal"] = np.array([s.tripped_goal for _m, s in window_statuses])
    pose = [m for i, key, m in messages if key == "platform/pose_estimate" and i < move_at][-1]
    data["start_pose_stamp"], data["start_pose"] = pose_from_cdr(pose.data)
    params = node_parameters()
    data["param_names"], data["param_values"] = np.array(list(params)), np.array(list(params.values()))
    data["source"] = json.dumps({**source, "mcap": mcap_name}, sort_keys=True)
    out.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out, **data)
    return data


def run_source(run_dir: Path) -> dict:
    """Which run this is: from its summary.json, the options it was run with and the checkout's commit."""
    summary = json.loads((run_dir / "summary.json").read_text())
    commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    return {"scenario": summary["scenario"], "scenario_file": f"config/{SCENARIO}", "run_options": list(RUN_OPTIONS),
            "plant": summary["plant"]["kind"], "plant_seed": summary["plant"]["seed"], "commit": commit,
            "made_by": "tools/record_guard_events.py"}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "test" / "data" / "guard_trip_events.npz")
    parser.add_argument("--run", type=Path, help="a run folder the tissue scenario wrote, run with the options above "
                        "(default: run it)")
    parser.add_argument("--domain-id", type=int, default=None, help="ROS_DOMAIN_ID of the run")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="guard_events_") as tmp:
        run_dir = args.run
        if run_dir is None:
            run_dir = Path(tmp) / "run"
            run_scenario(run_dir, args.domain_id)
        data = extract(run_dir, args.out, run_source(run_dir))
    print(f"{args.out}: {os.path.getsize(args.out) / 1024:.0f} KiB, {data['states_stamp'].size} states, "
          f"{data['wrench_stamp'].size} estimates, {data['status_log_ns'].size} guard statuses; {data['source']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
