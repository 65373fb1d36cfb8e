"""What a finished run did, analysed from every file of its run folder (also after a failure or an
interruption): every vibration that started, the streams, what the recording covers, the limits, the bounds,
and the report written by ``stewart-vibration report``.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from .run_console import log


def summarize(robot, record, summary: dict, scenario, out: Path, robot_config: str | None) -> None:
    """Analyse what ran (also after a failure or an interruption) from every file of the run folder: every
    vibration that started, the streams, what the recording covers (gaps, cut files, restarts), the limits
    over the recorded states, the bounds; write the report. Problems change the verdict."""
    from ..analysis.run_coverage import recording_coverage, recording_problems, restart_gaps, stream_summary
    from ..analysis.run_signals import load_signals
    from ..analysis.run_verdict import check_bounds, limit_summary
    from ..analysis.tissue_figures import summarize_tissue
    from ..analysis.vibration_figures import summarize_vibration

    try:  # the 500 Hz streams only around the vibrations; the limits are checked over every state as it is read
        signals = load_signals(out, windows=vibration_windows(record), robot=robot)
    except Exception as exc:  # noqa: BLE001 - an unreadable log is a failed run, said in one line
        summary["problems"].append(f"the MCAP cannot be analysed: {type(exc).__name__}: {exc}")
        return
    # the recording ends where the recorder stopped (its own clock: a recorder that lags behind the runner has
    # not yet received what the runner's clock says), or, without its word, at the runner's clock then
    stopped = (record.recorder_stats or {}).get("stopped_at_s")
    end = stopped if isinstance(stopped, (int, float)) and stopped > 0 else record.recording_span[1]
    span = (record.recording_span[0], end) if None not in (record.recording_span[0], end) else None
    summary["recording"] = recording_coverage(signals, span)
    summary["restarts"] = restart_gaps(signals, record.restarts)
    summary["problems"] += recording_problems(summary["recording"], summary["restarts"])
    nominal = robot.home_pose
    for step_move, vib in pair_vibrations(record):
        nominal = np.asarray(step_move["target"]) if step_move else nominal
        try:
            result = summarize_vibration(robot, signals, nominal, vib["parameters"], vib.get("t0", vib["start_time"]))
        except Exception as exc:  # noqa: BLE001 - e.g. interrupted before it vibrated
            summary["problems"].append(f"vibration starting at {vib['start_time']:.3f} s cannot be analysed: "
                                       f"{type(exc).__name__}: {exc}")
            continue
        result["failure"] = vib.get("failure")
        result["closed_loop"] = {key: vib[key] for key in ("loop_corrections", "demand_correction",
                                                           "stale_identification") if key in vib}
        summary["vibrations"].append(result)
    summary["tissue"] = summarize_tissue(signals, [(v["t0"], float(v["parameters"]["duration_s"]))
                                                   for v in record.vibrations if "t0" in v])
    summary["streams"] = stream_summary(signals)
    summary["limits"] = limit_summary(robot, signals)
    summary["bound_failures"] = check_bounds(summary, scenario.bounds)
    cut = any(not f["complete"] for f in summary["recording"]["files"])
    summary["report_dir"] = write_report(out, out / "report", robot_config, allow_truncated=cut)
    if summary["report_dir"] is None:
        summary["problems"].append("the report could not be written (see the log above)")


WINDOW_MARGIN_S = 1.5  # s of states kept before and after a vibration: its start is found up to 1 s early


def vibration_windows(record) -> list[tuple[float, float]]:
    """The spans (sim s) whose states the figures of the run's vibrations read: each from its start (or the
    start the runner asked for) to its end, WINDOW_MARGIN_S either side."""
    windows = []
    for vib in record.vibrations:
        start = float(vib.get("t0", vib["start_time"]))
        duration = float(vib.get("parameters", {}).get("duration_s", 0.0))
        windows.append((start - WINDOW_MARGIN_S, start + duration + WINDOW_MARGIN_S))
    return windows


def pair_vibrations(record):
    """Each vibration with the last move that preceded it (its nominal pose)."""
    pairs = []
    for vib in record.vibrations:
        before = [m for m in record.moves if m["time"] <= vib["start_time"]]
        pairs.append((before[-1] if before else None, vib))
    return pairs


def write_report(run: Path, report_dir: Path, robot_config: str | None, allow_truncated: bool = False) -> str | None:
    """Run ``stewart-vibration report`` on the run folder with the run's robot (every file; cut ones too when
    ``allow_truncated``: the summary already names them); returns the directory, or None if it failed."""
    robot = ["--robot", robot_config] if robot_config else []
    result = subprocess.run([sys.executable, "-m", "stewart_vibration", *robot, "report", str(run), "--out",
                             str(report_dir), *(["--allow-truncated"] if allow_truncated else [])],
                            capture_output=True, text=True, timeout=600)
    if result.returncode != 0:
        log(f"report failed: {result.stderr.strip()[-500:]}")
        return None
    return str(report_dir)
