"""The suite's node processes for one run (no rclpy): start each node with the run's arguments, watch them,
restart them under --keep-running, stop them and say which ended badly.

The ROS side of the bring-up (readiness, lifecycle, the recorder's stop) is ``nodes.suite_client``; the
scenario's steps are ``runtime.steps``; ``nodes.suite_runner`` puts the three together.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

from ..install import default_config_dir
from ..safe_yaml import load_yaml
from .processes import NodeProcess, ros_environment, start_python_module
from .run_options import RunOptions, RunRecord
from .suite import OPTIONAL_NODES, SUITE_NODES, SUITE_PARAMS_FILE

CLEAN_EXITS = (0, -2, 130)  # normal exit, SIGINT
# topics whose lost samples the summary prints but that do not fail the run: the emulator keeps 10 /clock samples
# (0.1 s), so a recorder held up that long on a busy machine misses some, and every recorded message carries its
# own stamp (the analysis never needs /clock)
LOSS_REPORTED_ONLY = frozenset({"/clock"})


def recorder_stats(log_text: str) -> dict | None:
    """The recorder's counts of its last file from its log (the last whole MCAP_RECORDER_STATS line: on a full
    disk the last one may be cut)."""
    for line in reversed([x for x in log_text.splitlines() if x.startswith("MCAP_RECORDER_STATS ")]):
        try:
            stats = json.loads(line.split(" ", 1)[1])
        except ValueError:
            continue
        if isinstance(stats, dict):
            return stats
    return None


def recorder_failures(stats: dict | None) -> list[str]:
    """What the recorder's counts of its last file make a failed run: messages dropped (its queue full),
    samples lost before they reached it (but /clock's: LOSS_REPORTED_ONLY), a write that failed."""
    if not stats:
        return []
    failures = []
    if stats.get("dropped", 0):
        failures.append(f"the recorder dropped {stats['dropped']} of {stats['received']} messages")
    lost = {t: n for t, n in (stats.get("lost_per_topic") or {}).items() if t not in LOSS_REPORTED_ONLY}
    if lost:
        topics = ", ".join(f"{t} {n}" for t, n in sorted(lost.items()))
        failures.append(f"{sum(lost.values())} samples were lost before they reached the recorder (sequence "
                        f"gaps: {topics})")
    if stats.get("failure"):
        failures.append(f"the recording failed: {stats['failure']['reason']}")
    return failures


def node_arguments(options: RunOptions) -> dict[str, list[str]]:
    """Per node name, its ``--ros-args`` for this run: namespace, the suite's parameter file and the run's own
    settings (real-time factor and lockstep, output folder, tissue, the plant for the emulator alone, and the robot
    for every node that reads one; the emulator waits to be configured and activated)."""
    params = options.params_file or default_config_dir() / SUITE_PARAMS_FILE
    common = ["--ros-args", "-r", f"__ns:={options.namespace}", "--params-file", str(params)]
    if options.hardware_params_file is not None:  # after the suite's: its values win
        common += ["--params-file", str(Path(options.hardware_params_file).resolve())]
    extra = {
        "hardware_emulator": ["-p", f"real_time_factor:={options.real_time_factor}", "-p", "autostart:=false",
                              "-p", f"lockstep:={str(options.lockstep).lower()}"],
        "mcap_recorder": ["-p", f"output_dir:={Path(options.out_dir).resolve()}"],
        "vibration_planner": ["-p", f"closed_loop:={str(options.vibration_control == 'closed_loop').lower()}"],
    }
    if options.identification_file is not None and options.vibration_control != "off":  # reused where it holds
        extra["vibration_planner"] += ["-p", f"identification_file:={Path(options.identification_file).resolve()}"]
    if options.plant_config:  # the robot as built: the emulator alone reads it
        extra["hardware_emulator"] += ["-p", f"plant_config:={options.plant_config}"]
        if options.plant_seed is not None:
            extra["hardware_emulator"] += ["-p", f"plant_seed:={options.plant_seed}"]
    if options.tissue_config:
        for name in ("hardware_emulator", "kinematics"):
            extra[name] = extra.get(name, []) + ["-p", f"tissue_config:={options.tissue_config}"]
    nodes = SUITE_NODES + [OPTIONAL_NODES[key] for key in options.extra_nodes]
    if options.robot_config:
        robot = ["-p", f"robot_config:={Path(options.robot_config).resolve()}"]
        for node in nodes:
            if node.robot_config:
                extra[node.name] = extra.get(node.name, []) + robot
    return {node.name: common + extra.get(node.name, []) for node in nodes}


class SuiteProcesses:
    """The run's node processes (each its own process group; see ``processes``)."""

    def __init__(self, options: RunOptions, record: RunRecord):
        self.options, self.record = options, record
        self.procs: list[NodeProcess] = []
        self._dead: set[str] = set()  # reported by supervise(), not again by stop()

    def start(self) -> None:
        """Start every node of the run on its ROS domain, logs in <out>/logs."""
        opts = self.options
        for path in (opts.params_file, opts.hardware_params_file):  # refused here, with its reason, rather than
            if path is not None:  # by every node's rcl
                load_yaml(path, "node parameter file")
        env = ros_environment(opts.domain_id)
        Path(opts.out_dir).mkdir(parents=True, exist_ok=True)
        self.record.log_dir = Path(opts.out_dir) / "logs"
        modules = {node.name: node.module for node in SUITE_NODES + list(OPTIONAL_NODES.values())}
        for name, args in node_arguments(opts).items():
            self.procs.append(start_python_module(name, modules[name], args, env, self.record.log_dir))

    def dead(self) -> list[str]:
        """Names of the nodes that are no longer running."""
        return [p.name for p in self.procs if not p.alive()]

    def log_lines(self, node: str, marker: str) -> list[str]:
        """Lines of ``node``'s log that contain ``marker`` (e.g. the URL an optional node prints)."""
        proc = next((p for p in self.procs if p.name == node), None)
        return [line for line in proc.log_text().splitlines() if marker in line] if proc else []

    def recent_problems(self, per_node: int = 5) -> list[str]:
        """The last ``per_node`` WARN / ERROR lines of every node's log, "name: line" (what a failed step
        prints, so the reason is on the screen and not only in <out>/logs)."""
        lines = []
        for proc in self.procs:
            marked = [line for line in proc.log_text().splitlines() if "[WARN]" in line or "[ERROR]" in line]
            lines += [f"{proc.name}: {line.strip()}" for line in marked[-per_node:]]
        return lines

    def supervise(self, respawn: set[str], idle: Callable[[], None],
                  now: Callable[[], float | None] = lambda: None) -> None:
        """Keep the suite up until interrupted (--keep-running): a node that exits is reported and, when its
        name is in ``respawn``, started again with the same arguments (recorded with the sim time ``now()``
        its exit was seen: the run summary reports the gap it left); the others keep running. ``idle()``
        runs between the checks (the client spins there)."""
        progress = self.options.progress
        while True:
            for i, proc in enumerate(self.procs):
                code = proc.popen.poll()
                if code is None or proc.name in self._dead:
                    continue
                if proc.name in respawn:
                    progress(f"{proc.name} exited with code {code}; restarting it (log: {proc.log_path})")
                    self.record.restarts.append({"node": proc.name, "exit_code": code, "sim_time_s": now()})
                    self.procs[i] = proc.restart()
                else:
                    progress(f"{proc.name} exited with code {code}; not restarted (--respawn does not name it); "
                             "the other nodes keep running")
                    self.record.failures.append(f"{proc.name} exited with code {code} during --keep-running "
                                                f"(log: {proc.log_path})")
                    self._dead.add(proc.name)
            idle()

    def stop(self) -> None:
        """Stop every process (last started first); record a failure for every node that exited abnormally or
        could not be stopped, the recorder's counts, and its drops."""
        for proc in reversed(self.procs):
            died = proc.popen.poll()
            if proc.name in self._dead:
                continue
            code = proc.stop(grace_s=10.0)
            if code is None:
                self.record.failures.append(f"{proc.name} could not be stopped (log: {proc.log_path})")
            elif died is not None and died not in CLEAN_EXITS:
                self.record.failures.append(f"{proc.name} died during the run with exit code {died} "
                                            f"(log: {proc.log_path})")
            elif code not in CLEAN_EXITS:
                self.record.failures.append(f"{proc.name} exited with code {code} (log: {proc.log_path})")
            if proc.name == "mcap_recorder":
                self.record.recorder_stats = recorder_stats(proc.log_text())
        self.record.failures += recorder_failures(self.record.recorder_stats)
