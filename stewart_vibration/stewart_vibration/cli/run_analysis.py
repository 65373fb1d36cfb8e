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
    from ..analysis.vibration_scan import held_windows
    from ..mcap_log.reader import open_run

    try:  # the 500 Hz streams only around the vibrations (a long one's ends: its middle is summed in a second
        # read); the limits are checked over every state as it is read
        run = open_run(out, allow_truncated=True)
        windows, spans = held_windows(vibration_spans(record), WINDOW_MARGIN_S, streaming=not tissue_recorded(run))
        signals = load_signals(run, windows=windows, robot=robot)
        streamed = steady_streams(robot, record, signals, spans, run)
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
    for (nominal, vib), stream in zip(nominal_poses(robot, record), streamed, strict=True):
        try:
            result = summarize_vibration(robot, signals, nominal, vib["parameters"], vib.get("t0", vib["start_time"]),
                                         stream)
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


def vibration_spans(record) -> list[tuple[float, float]]:
    """(start, duration) (sim s) of each vibration of the run: from its start (or the start the runner asked
    for), its planned duration."""
    return [(float(vib.get("t0", vib["start_time"])), float(vib.get("parameters", {}).get("duration_s", 0.0)))
            for vib in record.vibrations]


def nominal_poses(robot, record) -> list:
    """Each vibration with the pose it was planned at: the target of the last move that preceded it (home
    before any move)."""
    nominal, out = robot.home_pose, []
    for step_move, vib in pair_vibrations(record):
        nominal = np.asarray(step_move["target"]) if step_move else nominal
        out.append((nominal, vib))
    return out


def steady_streams(robot, record, signals: dict, spans: list, run) -> list:
    """The middle of each long vibration, summed in a second read of the open ``run``
    (``vibration_scan.stream_steady``); None for a vibration held whole, or one whose frame cannot be found (its
    figures then say why)."""
    from ..analysis.vibration_figures import vibration_frame
    from ..analysis.vibration_scan import stream_steady

    frames = []
    for (nominal, vib), span in zip(nominal_poses(robot, record), spans, strict=True):
        frame = None
        if span is not None:  # a vibration held whole needs no frame here
            try:
                frame = vibration_frame(robot, signals, nominal, vib["parameters"], vib.get("t0", vib["start_time"]))
            except Exception:  # noqa: BLE001 - summarize_vibration says why, with the same frame
                span = None
        frames.append((frame, span))
    return stream_steady(run, frames)


def tissue_recorded(run) -> bool:
    """Whether the run (an open RunReader / RunFiles) recorded an applied tissue wrench (its figures compare every
    estimate with it)."""
    from ..analysis.run_signals import TISSUE_KEYS, recorded_keys

    return bool(recorded_keys(run, TISSUE_KEYS))


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
