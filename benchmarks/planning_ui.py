"""The main job with the planning UI open in a browser: do the suite's figures still pass, and
what does the UI cost?

Runs `stewart-vibration run --ui` (the main scenario: move to the paper's pose, 35 Hz / 0.3 g along the
tibia axis, return), opens the URL the planning_ui node logs in a headless Chromium (Debian package) as
soon as it appears, keeps the page streaming through the run, and samples every process's CPU time
(/proc/<pid>/stat, user + system) every 0.5 s: cores = CPU seconds / wall seconds, over the whole run
(page open to the last sample) and over the vibration. Then prints the run's figures against their
bounds (summary.json) and what the page received. ``--baseline`` first runs the same job without the UI.

``--no-page`` also runs it with the UI node up but no page open (its 500 Hz subscriptions are then dropped).

Run: .venv/bin/python benchmarks/planning_ui.py [--duration 3] [--baseline] [--no-page] [--json]
Exit code 0 when every run passed its bounds (exit code 0), 1 otherwise.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE.parent / "test")]
from cdp_browser import Browser, chromium_binary  # noqa: E402 - the tests' CDP driver
from suite_cpu import children, cpu_seconds, process_name  # noqa: E402 - the suite benchmark's /proc readers


def run_job(out: Path, duration: float | None, ui: bool, open_page: bool = True) -> dict:
    cmd = [sys.executable, "-m", "stewart_vibration", "run", "--out", str(out / "run")]
    cmd += ["--duration", str(duration)] if duration else []
    cmd += ["--ui"] if ui else []
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1,
                            start_new_session=True)
    lines: list[str] = []
    marks: dict[str, float] = {}
    url: list[str] = []

    def read() -> None:
        for line in proc.stdout:
            lines.append(line)
            found = re.search(r"planning UI at (http://\S+)", line)
            if found:
                url.append(found.group(1))
            if ": vibrating: started" in line:
                marks["vibration"] = time.monotonic()
            if ": vibration done:" in line:
                marks["vibration_done"] = time.monotonic()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    browser = None
    samples: list[tuple[float, dict]] = []  # (wall, {pid: cpu s})
    names: dict[int, str] = {}
    page = {}
    try:
        if ui and open_page:
            deadline = time.monotonic() + 120
            while not url and time.monotonic() < deadline and proc.poll() is None:
                time.sleep(0.05)
            if not url:
                raise RuntimeError("no planning UI URL in the run's output:\n" + "".join(lines[-20:]))
            browser = Browser(out / "chromium")
            browser.navigate(url[0])
            browser.wait_for("window.ui && ui.stats.frames > 0", 30, "the page's first frame")
        while proc.poll() is None:
            pids = [proc.pid, *children(proc.pid)]
            if browser is not None:
                pids += [browser.proc.pid, *children(browser.proc.pid)]
            for pid in pids:
                if pid not in names:
                    names[pid] = "chromium" if browser is not None and (
                        pid == browser.proc.pid or pid in children(browser.proc.pid)) else process_name(pid)
            names[proc.pid] = "runner"
            samples.append((time.monotonic(), {pid: cpu_seconds(pid) for pid in pids}))
            if browser is not None:
                try:
                    page = browser.evaluate("ui.stats")
                except Exception:  # noqa: BLE001 - the node is gone at the very end
                    pass
            time.sleep(0.5)
        code = proc.wait()
    finally:
        if browser is not None:
            browser.close()
        if proc.poll() is None:
            proc.kill()
    reader.join(timeout=5)
    summary_path = out / "run" / "summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.exists() else {}
    return {"ui": ui, "page_open": ui and open_page, "exit_code": code, "summary": summary, "page": page,
            "log_tail": "".join(lines[-8:]),
            "cores_run": cores(samples, names, None, None),
            "cores_vibration": cores(samples, names, marks.get("vibration"), marks.get("vibration_done"))}


def cores(samples, names, start, end) -> dict:
    """Per process name: CPU seconds / wall seconds between its first and last sample in [start, end]
    (a process that exits, as every node does at the end, counts up to its last sample)."""
    inside = [s for s in samples if (start is None or s[0] >= start) and (end is None or s[0] <= end)]
    seen: dict[int, list] = {}  # pid -> [(t, cpu) first, (t, cpu) last]
    for t, values in inside:
        for pid, cpu in values.items():
            if cpu is not None:
                seen.setdefault(pid, [(t, cpu), (t, cpu)])[1] = (t, cpu)
    out: dict[str, float] = {}
    for pid, ((t0, c0), (t1, c1)) in seen.items():
        if t1 - t0 > 1.0:
            out[names[pid]] = out.get(names[pid], 0.0) + (c1 - c0) / (t1 - t0)
    out["wall_s"] = inside[-1][0] - inside[0][0] if len(inside) > 1 else 0.0
    return out


def figures(summary: dict) -> dict:
    vib = (summary.get("vibrations") or [{}])[0]
    force = vib.get("force") or {}
    streams = summary.get("streams") or {}
    return {
        "pose_error_um": max((m["pose_error_m"] * 1e6 for m in summary.get("moves", [])), default=None),
        "direction_error_deg": vib.get("direction_error_deg"),
        "amplitude_error_pct": vib["amplitude_error"] * 100 if "amplitude_error" in vib else None,
        "leg_phase_error_deg": max(vib.get("leg_phase_error_deg") or [None] * 0, default=None),
        "force_error_worst_leg_pct": force["worst_leg_vs_largest_amplitude"] * 100 if force else None,
        "worst_stream_ratio": streams.get("worst_ratio"), "states_lost": streams.get("lost"),
        "bound_failures": summary.get("bound_failures"), "problems": summary.get("problems"),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--duration", type=float, default=None, help="vibration duration (default: the scenario's)")
    parser.add_argument("--baseline", action="store_true", help="first run the same job without the UI")
    parser.add_argument("--no-page", action="store_true", help="also run with the UI node but no page open")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    if chromium_binary() is None:
        print("needs chromium: apt-get install -y chromium", file=sys.stderr)
        return 2
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        for ui in ([False] if args.baseline else []) + [True]:
            runs.append(run_job(Path(tmp) / ("ui" if ui else "baseline"), args.duration, ui))
        if args.no_page:
            runs.append(run_job(Path(tmp) / "no_page", args.duration, True, open_page=False))
    ok = all(r["exit_code"] == 0 for r in runs)
    if args.json:
        print(json.dumps([{**{k: v for k, v in r.items() if k != "summary"}, "figures": figures(r["summary"])}
                          for r in runs], indent=2))
        return 0 if ok else 1
    for r in runs:
        label = ("with the planning UI open in Chromium" if r["page_open"] else "with the planning UI node, no page"
                 if r["ui"] else "baseline (no UI)")
        print(f"== main job {label}: exit code {r['exit_code']}")
        for key, value in figures(r["summary"]).items():
            print(f"  {key:<28}{value if not isinstance(value, float) else f'{value:.4g}'}")
        for span in ("cores_run", "cores_vibration"):
            c = dict(r[span])
            wall = c.pop("wall_s", 0.0)
            print(f"  CPU ({'whole run' if span == 'cores_run' else 'vibration'}, {wall:.1f} s): " +
                  ", ".join(f"{k} {v:.3f}" for k, v in sorted(c.items(), key=lambda kv: -kv[1])) + " cores")
        if r["page"]:
            p = r["page"]
            print(f"  page received {p['frames']} frames, {p['vibSamples']} vib samples, {p['forceSamples']} force "
                  f"samples; {p['plotDraws']} plot redraws")
    print("PASS" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
