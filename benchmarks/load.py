"""The main job under CPU load: N runs of `stewart-vibration run` with K busy CPU hogs beside it.

Each hog is a plain `python -c "while True: pass"` process, started before a run and ended after it. Per
run the table gives: pass/fail (the exit code: every bound of the scenario), the vibration's active time
against the planned one, the platform amplitude and direction error, the windows the emulator accepted and
refused, the worst ratio of estimates to joint states and the states the nodes lost.

Run: .venv/bin/python benchmarks/load.py [--runs 10] [--hogs 2] [--json]
Exit code 0 when every run passed.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from load_runs import cpu_hogs, summarise


def one_run(out: Path, hogs: int, timeout_s: float = 900.0) -> dict:
    with cpu_hogs(hogs):
        started = time.monotonic()
        result = subprocess.run([sys.executable, "-m", "stewart_vibration", "run", "--out", str(out)],
                                capture_output=True, text=True, timeout=timeout_s)
        wall = time.monotonic() - started
    summary_path = out / "summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.exists() else {}
    vib = (summary.get("vibrations") or [{}])[0]
    streams = summary.get("streams") or {}
    return {
        "exit_code": result.returncode,
        "passed": result.returncode == 0,
        "wall_s": wall,
        "active_s": vib.get("active_duration_s"),
        "planned_active_s": vib.get("planned_active_duration_s"),
        "amplitude_error": vib.get("amplitude_error"),
        "direction_error_deg": vib.get("direction_error_deg"),
        "windows": streams.get("windows"),
        "worst_ratio": streams.get("worst_ratio"),
        "lost": streams.get("lost"),
        "failure": summary.get("failure") or "; ".join(summary.get("bound_failures") or summary.get("problems") or []),
        "tail": result.stdout[-1500:] if result.returncode else "",
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--hogs", type=int, default=2)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.runs):
            rows.append(one_run(Path(tmp) / f"run{i}", args.hogs))
            if not args.json:
                r = rows[-1]
                windows = r["windows"] or {}

                def fmt(value, scale=1.0, digits=3):
                    return "-" if value is None else f"{value * scale:.{digits}f}"

                print(f"run {i + 1:2d}: {'PASS' if r['passed'] else 'FAIL'}  active {fmt(r['active_s'])} s of "
                      f"{fmt(r['planned_active_s'])} s  amplitude error {fmt(r['amplitude_error'], 100)} %  "
                      f"direction error {fmt(r['direction_error_deg'], 1, 4)} deg  windows accepted "
                      f"{windows.get('accepted', '-')} refused {windows.get('refused', '-')}  estimates/states "
                      f"{fmt(r['worst_ratio'], 100, 2)} %  lost {r['lost']}  ({r['wall_s']:.0f} s wall)", flush=True)
                if not r["passed"]:
                    print(f"        {r['failure']}\n{r['tail']}", flush=True)
    return summarise(rows, "passed", args.hogs, args.json, "passed every bound")


if __name__ == "__main__":
    sys.exit(main())
