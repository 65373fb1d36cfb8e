"""The whole test suite N times in a row with K busy CPU hogs beside it (a flakiness check).

Each run is the README's test command (``./tools/test``: ruff, mypy, pytest) with a JUnit report; the
hogs (see load_runs.py) spin for the whole run. Per run it prints the exit code, the counts of passed,
failed, errored and skipped tests, the wall time, the CPU the hogs took (cores, so a reader can see they
really competed) and the failing test ids.

Run: .venv/bin/python benchmarks/suite_under_load.py [--runs 3] [--hogs 1] [--json] [-- PYTEST ARGS]
Exit code 0 only when every run exited 0 with no failed or errored test.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

from load_runs import cpu_hogs, summarise

REPO = Path(__file__).resolve().parents[1]
CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of a live process, from /proc/PID/stat."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


def junit_counts(report: Path) -> dict:
    """Counts and failing test ids from a pytest JUnit XML report (zeros and a note if there is none)."""
    if not report.exists():
        return {"tests": 0, "failed": 0, "errors": 0, "skipped": 0, "failing": ["no JUnit report written"]}
    root = ET.parse(report).getroot()
    suites = [root] if root.tag == "testsuite" else list(root.iter("testsuite"))
    counts = {key: sum(int(s.get(key, 0)) for s in suites) for key in ("tests", "failures", "errors", "skipped")}
    failing = [f"{case.get('classname')}::{case.get('name')}" for case in root.iter("testcase")
               if case.find("failure") is not None or case.find("error") is not None]
    return {"tests": counts["tests"], "failed": counts["failures"], "errors": counts["errors"],
            "skipped": counts["skipped"], "failing": failing}


def one_run(index: int, hogs: int, pytest_args: list[str], workdir: Path) -> dict:
    """One ./tools/test run beside ``hogs`` hogs; its verdict, counts, wall time and the hogs' CPU."""
    report = workdir / f"run{index}.xml"
    log = workdir / f"run{index}.log"
    with cpu_hogs(hogs) as procs, open(log, "w") as out:
        started = time.monotonic()
        code = subprocess.run([str(REPO / "tools" / "test"), "-q", f"--junitxml={report}", *pytest_args],
                              cwd=REPO, stdout=out, stderr=subprocess.STDOUT).returncode
        wall = time.monotonic() - started
        hog_cores = sum(cpu_seconds(p.pid) for p in procs) / wall if wall > 0 else 0.0
    counts = junit_counts(report)
    passed = counts["tests"] - counts["failed"] - counts["errors"] - counts["skipped"]
    ok = code == 0 and counts["failed"] == 0 and counts["errors"] == 0 and passed > 0
    return {"run": index, "exit_code": code, "passed": passed, **counts, "wall_s": round(wall, 1),
            "hog_cores": round(hog_cores, 2), "ok": ok,
            "log_tail": "" if ok else log.read_text()[-3000:]}


def main() -> int:
    """Run the suite ``--runs`` times beside ``--hogs`` hogs; exit 0 only if every run is green."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--hogs", type=int, default=1)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("pytest_args", nargs="*", help="passed on to pytest (after --)")
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(1, args.runs + 1):
            row = one_run(i, args.hogs, args.pytest_args, Path(tmp))
            rows.append(row)
            if not args.json:
                print(f"run {i}: exit {row['exit_code']}, {row['passed']} passed, {row['failed']} failed, "
                      f"{row['errors']} errors, {row['skipped']} skipped in {row['wall_s']:.0f} s; "
                      f"hogs took {row['hog_cores']:.2f} cores -> {'ok' if row['ok'] else 'FAIL'}", flush=True)
                for test_id in row["failing"]:
                    print(f"    failing: {test_id}")
                if row["log_tail"]:
                    print(row["log_tail"])
    return summarise(rows, "ok", args.hogs, args.json, "in a row green")


if __name__ == "__main__":
    sys.exit(main())
