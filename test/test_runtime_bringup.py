"""SuiteProcesses' report of what the nodes complained about (printed when a scenario step fails)."""

from __future__ import annotations

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
