"""The gap between the drawing and the robot as built: the main job's figures on the ideal plant and on the
realistic plant for N seeds, today's controller unchanged.

Per run (one `stewart-vibration run`, its summary.json): the worst pose error after a move (ground truth) and
the controller's estimate of it, the vibration's direction and amplitude error and off-axis ratio (ground
truth, and in the controller's view), the worst leg's amplitude and phase error, the worst leg's force
estimate error (RMS over the force amplitude, against the true forces), the peak true unit displacement, whether
the vibration ran or the units' travel protection stopped it, and the exit code (every bound).
A failed run is a row too: the gap is the point, and the run's own verdict is in its column.

Run: .venv/bin/python benchmarks/plant_gap.py [--seeds 10] [--json]
Exit code 0 when every run produced a summary (the realistic plant is expected to miss its bounds).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def one_run(out: Path, plant: str, seed: int | None, timeout_s: float = 900.0) -> dict:
    """One main job on ``plant`` (ideal / realistic) with ``seed``; its figures from summary.json."""
    command = [sys.executable, "-m", "stewart_vibration", "run", "--out", str(out), "--plant", plant]
    if seed is not None:
        command += ["--plant-seed", str(seed)]
    started = time.monotonic()
    result = subprocess.run(command, capture_output=True, text=True, timeout=timeout_s)
    wall = time.monotonic() - started
    path = out / "summary.json"
    summary = json.loads(path.read_text()) if path.exists() else {}
    moves = summary.get("moves") or []
    vib = (summary.get("vibrations") or [{}])[0]
    view = vib.get("controller_view") or {}
    force = vib.get("force") or {}

    def worst(values):
        return max(abs(v) for v in values) if values else None

    unit_travel = next((lim for lim in summary.get("limits") or [] if lim["name"] == "vibration unit displacement"),
                       None)
    failure = vib.get("failure") or summary.get("failure")  # a vibration stopped at once may have no record
    stopped = "ran" if not failure else ("unit over-travel" if "over-travel" in failure else "failed")

    row = {
        "plant": plant, "seed": seed, "exit_code": result.returncode, "wall_s": wall, "summarised": bool(summary),
        "pose_error_um": worst([m["pose_error_m"] * 1e6 for m in moves]),
        "estimate_error_um": worst([m.get("estimate_error_m", float("nan")) * 1e6 for m in moves]),
        "direction_error_deg": vib.get("direction_error_deg"),
        "amplitude_error_pct": None if vib.get("amplitude_error") is None else vib["amplitude_error"] * 100,
        "off_axis_ratio": vib.get("off_axis_ratio"),
        "leg_amplitude_error_pct": None if not vib.get("leg_amplitude_error") else
        worst(vib["leg_amplitude_error"]) * 100,
        "leg_phase_error_deg": worst(vib.get("leg_phase_error_deg") or []),
        "force_error_pct": None if force.get("worst_leg_relative") is None else force["worst_leg_relative"] * 100,
        "view_direction_error_deg": view.get("direction_error_deg"),
        "view_amplitude_error_pct": None if view.get("amplitude_error") is None else view["amplitude_error"] * 100,
        "unit_peak_um": None if unit_travel is None else unit_travel["worst"] * 1e6,
        "vibration": stopped if vib or failure else None, "vibration_failure": failure,
    }
    if failure:  # a stopped vibration's figures describe its ramp-out, not the vibration: no such figures
        row.update({key: None for key in VIBRATION_FIGURES})
    return row


VIBRATION_FIGURES = ("direction_error_deg", "amplitude_error_pct", "off_axis_ratio", "leg_amplitude_error_pct",
                     "leg_phase_error_deg", "force_error_pct", "view_direction_error_deg", "view_amplitude_error_pct")
COLUMNS = [("plant", "plant", "{}"), ("seed", "seed", "{}"), ("pose_error_um", "pose err um", "{:.2f}"),
           ("estimate_error_um", "estimate err um", "{:.3f}"), ("direction_error_deg", "dir err deg", "{:.3f}"),
           ("amplitude_error_pct", "amp err %", "{:.2f}"), ("off_axis_ratio", "off-axis", "{:.2e}"),
           ("leg_amplitude_error_pct", "leg amp err %", "{:.2f}"), ("leg_phase_error_deg", "leg phase deg", "{:.2f}"),
           ("force_error_pct", "force err %", "{:.2f}"), ("view_direction_error_deg", "view dir deg", "{:.3f}"),
           ("view_amplitude_error_pct", "view amp %", "{:.2f}"), ("unit_peak_um", "unit peak um", "{:.1f}"),
           ("vibration", "vibration", "{}"), ("exit_code", "exit", "{}")]


def table_row(row: dict) -> str:
    """One Markdown table row of ``row`` ("-" for a figure the run did not produce)."""
    cells = ["-" if row.get(key) is None else fmt.format(row[key]) for key, _, fmt in COLUMNS]
    return "| " + " | ".join(cells) + " |"


def spread_row(rows: list[dict], name: str, pick) -> dict:
    """A row of ``pick`` (median, max) over ``rows`` of each figure's magnitude, named ``name``."""
    out: dict = {"plant": f"realistic {name}", "seed": f"{len(rows)} seeds"}
    for key, _, _ in COLUMNS[2:-2]:
        values = [abs(r[key]) for r in rows if r.get(key) is not None]
        out[key] = float(pick(values)) if values else None
    out["vibration"] = f"{sum(r.get('vibration') == 'ran' for r in rows)} ran"
    out["exit_code"] = "-"
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=10, help="realistic plants 1..N (default 10)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        runs = [("ideal", None)] + [("realistic", seed) for seed in range(1, args.seeds + 1)]
        if not args.json:
            print("| " + " | ".join(title for _, title, _ in COLUMNS) + " |")
            print("|" + "---|" * len(COLUMNS))
        for plant, seed in runs:
            rows.append(one_run(Path(tmp) / f"{plant}{seed or ''}", plant, seed))
            if not args.json:
                print(table_row(rows[-1]), flush=True)
    realistic = [r for r in rows if r["plant"] == "realistic" and r["summarised"]]
    spread = [spread_row(realistic, name, pick) for name, pick in (("median", np.nanmedian), ("worst", np.nanmax))]
    if args.json:
        print(json.dumps({"runs": rows, "realistic": dict(zip(("median", "worst"), spread))}, indent=2))
    elif realistic:
        for row in spread:
            print(table_row(row))
    missing = [f"{r['plant']} seed {r['seed']}" for r in rows if not r["summarised"]]
    if missing:
        print(f"no summary from: {', '.join(missing)}", file=sys.stderr)
    return 0 if not missing else 1


if __name__ == "__main__":
    sys.exit(main())
