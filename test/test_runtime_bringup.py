"""SuiteProcesses' report of what the nodes complained about (printed when a scenario step fails)."""

from __future__ import annotations

from pathlib import Path

from stewart_vibration.runtime.bringup import SuiteProcesses
from stewart_vibration.runtime.processes import NodeProcess


def test_recent_problems_lists_the_last_warnings_and_errors_of_each_node(tmp_path):
    logs = {
        "kinematics": ["[INFO] [1.0] [kinematics]: ready"]
                      + [f"[WARN] [{i}.0] [kinematics]: force guard: slow move {i}" for i in range(7)],
        "estimator": ["[INFO] [1.0] [leg_force_estimator]: ready", "[ERROR] [2.0] [leg_force_estimator]: stalled",
                      "  continuation line without a level"],
        "planner": ["[INFO] [1.0] [vibration_planner]: ready"],
    }
    processes = SuiteProcesses.__new__(SuiteProcesses)
    processes.procs = []
    for name, lines in logs.items():
        path = tmp_path / f"{name}.log"
        path.write_text("\n".join(lines) + "\n")
        processes.procs.append(NodeProcess(name=name, popen=None, log_path=path))  # type: ignore[arg-type]
    problems = processes.recent_problems(per_node=5)
    kinematics = [line for line in problems if line.startswith("kinematics: ")]
    assert [line.rsplit(" ", 1)[-1] for line in kinematics] == ["2", "3", "4", "5", "6"]  # the last five, in order
    assert problems[-1] == "estimator: [ERROR] [2.0] [leg_force_estimator]: stalled"
    assert not any(line.startswith("planner") or "[INFO]" in line for line in problems)
    missing = NodeProcess(name="gone", popen=None, log_path=tmp_path / "absent.log")  # type: ignore[arg-type]
    processes.procs = [missing]
    assert processes.recent_problems() == []


def test_the_robot_reaches_every_node_that_reads_one(tmp_path):
    """--robot (RunOptions.robot_config) is passed, as an absolute path, to every node whose parameter table
    declares robot_config (and whose source declares that table), main job and optional nodes alike; none is
    left on the default robot."""
    import ast
    import importlib.util

    from stewart_vibration.parameters.tables import NODE_PARAMETERS
    from stewart_vibration.runtime.bringup import node_arguments
    from stewart_vibration.runtime.run_options import RunOptions
    from stewart_vibration.runtime.suite import OPTIONAL_NODES, SUITE_NODES

    def declared_table(module: str) -> str:
        """The name of the table the node's source passes to declare_table."""
        source = open(importlib.util.find_spec(module).origin).read()
        (table,) = [n.args[1].id for n in ast.walk(ast.parse(source)) if isinstance(n, ast.Call)
                    and getattr(n.func, "id", "") == "declare_table" and len(n.args) == 2]
        return table

    nodes = SUITE_NODES + list(OPTIONAL_NODES.values())
    for node in nodes:  # each node declares its own table
        assert declared_table(node.module) == node.name.upper(), node.name
    readers = {n.name for n in nodes if any(s.name == "robot_config" for s in NODE_PARAMETERS[n.name])}
    assert readers == {n.name for n in nodes if n.robot_config}  # the suite's list says which nodes read one
    assert {"hardware_emulator", "kinematics", "vibration_planner", "leg_force_estimator"} <= readers
    relative = "short.yaml"
    args = node_arguments(RunOptions(robot_config=relative, out_dir=tmp_path, extra_nodes=tuple(OPTIONAL_NODES)))
    expected = f"robot_config:={(Path.cwd() / relative).resolve()}"
    assert {name for name, a in args.items() if expected in a} == readers
    default = node_arguments(RunOptions(out_dir=tmp_path))
    assert not any("robot_config" in " ".join(a) for a in default.values())  # no --robot: each node's default


def test_the_recorder_stats_come_from_its_last_whole_line():
    from stewart_vibration.runtime.bringup import recorder_stats

    log = ('MCAP_RECORDER_STATS {"written": 1}\nother line\nMCAP_RECORDER_STATS {"written": 2}\n'
           'MCAP_RECORDER_STATS {"written": 3, "per_to')  # the last one cut by a full disk
    assert recorder_stats(log) == {"written": 2}
    assert recorder_stats("nothing here") is None


def test_what_the_recorder_counts_fails_a_run():
    from stewart_vibration.runtime.bringup import recorder_failures

    assert recorder_failures(None) == [] and recorder_failures({"dropped": 0, "lost_per_topic": {}}) == []
    assert recorder_failures({"lost_per_topic": {"/clock": 8}}) == []  # printed, not a failure
    failures = recorder_failures({"dropped": 2, "received": 10, "lost_per_topic": {"/clock": 8, "/diagnostics": 3},
                                  "failure": {"reason": "writing x failed: No space left on device (ENOSPC)"}})
    assert failures == ["the recorder dropped 2 of 10 messages",
                        "3 samples were lost before they reached the recorder (sequence gaps: "
                        "/diagnostics 3)",
                        "the recording failed: writing x failed: No space left on device (ENOSPC)"]


def test_a_hardware_parameter_file_comes_after_the_suites_and_reaches_every_node(tmp_path):
    """--params-file (RunOptions.hardware_params_file): every node gets the suite's parameter file, then this one
    (rcl applies them in order: the hardware's values win), as an absolute path."""
    from stewart_vibration.install import default_config_dir
    from stewart_vibration.runtime.bringup import SUITE_PARAMS_FILE, node_arguments
    from stewart_vibration.runtime.run_options import RunOptions

    args = node_arguments(RunOptions(out_dir=tmp_path, hardware_params_file=Path("datasheet.yaml")))
    suite = str(default_config_dir() / SUITE_PARAMS_FILE)
    for name, a in args.items():
        files = [a[i + 1] for i, v in enumerate(a) if v == "--params-file"]
        assert files == [suite, str((Path.cwd() / "datasheet.yaml").resolve())], (name, files)
    plain = node_arguments(RunOptions(out_dir=tmp_path))
    assert all(a.count("--params-file") == 1 for a in plain.values())
