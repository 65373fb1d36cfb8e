"""Run report from an MCAP: summary (JSON + markdown) and PNG plots, for whatever topics exist.

Topics are matched by suffix so namespaced runs work: ``legs/joint_states``
(leg_* lengths, vib_* displacements, leg_* efforts = measured axial force),
``ground_truth/platform_pose``, ``legs/force_estimate``, ``/diagnostics`` and ``/rosout``
(events); with a soft-tissue run also ``ground_truth/tissue_wrench`` (applied) against
``platform/external_wrench_estimate``, and the force guard's trips
(``kinematics/guard_status``). Times in the plots are seconds from the first message; lengths and
displacements are plotted in mm (labelled), everything in the JSON is SI.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from ..kinematics.robot_config import load_robot
from ..mcap_log.reader import RunFiles, RunReader, open_run
from ..output_files import write_text_whole
from ..robot import LEG_NAMES, VIB_NAMES, Robot
from .fits import dominant_sinusoid
from .plot_pool import PlotPool
from .report_data import report_data
from .vibration_figures import leg_force_error, platform_vibration

EVENT_WORDS = ("start", "stop", "e-stop", "emergency", "estop", "reset")


def _find(reader: RunReader | RunFiles, suffix: str) -> str | None:
    for t in reader.topics():
        if t.topic.endswith(suffix) and t.message_count:
            return t.topic
    return None


def _events(reader: RunReader | RunFiles, t0: int) -> list[dict]:
    """Every /diagnostics status, and the /rosout lines that are warnings or name a start, stop or reset, with
    their log time (s from ``t0``, ns)."""
    events = []
    for topic in ("/diagnostics", "/rosout"):
        if _find(reader, topic) != topic:
            continue
        for raw, msg in reader.decoded([topic]):
            when = (raw.log_time - t0) / 1e9
            if topic == "/diagnostics":
                for s in msg.status:
                    level = int.from_bytes(s.level, "little") if isinstance(s.level, bytes) else int(s.level)
                    events.append({"t_s": when, "source": s.name, "level": level, "text": s.message})
            elif int(msg.level) >= 30 or any(w in msg.msg.lower() for w in EVENT_WORDS):
                events.append({"t_s": when, "source": msg.name, "level": int(msg.level), "text": msg.msg})
    return events


def summarize(reader: RunReader | RunFiles, data: dict, signals: dict, robot: Robot) -> dict:
    """The JSON summary: counts, leg amplitudes/frequencies, platform vibration, force error, events.

    The platform's vibration and the force error come from the run summary's own functions over the
    steady vibration (``report_data``: its middle minute at most), at the legs' median fitted frequency.

    Args:
        reader: the open run.
        data: the run's data (``report_data.report_data``, with "events").
        signals: ``run_signals.load_signals`` of the same run.
        robot: removes an applied tissue's leg forces from the measured efforts, as the run summary does.

    Returns:
        A JSON-ready dict (SI units; times in s from the first message): file, complete, message_count,
        topics, leg_length_mean_m, vibration_window_s, analysed_window_s, per-leg vibration, platform, force errors,
        tissue_wrench, guard_trips and events, each only where the data exist.

    Raises:
        ValueError: fewer than 4 ground-truth poses in the steady window (``vibration_figures.platform_vibration``).
        InvalidInputError: fewer than 4 measured efforts lie within the force estimates' time span, or a
            fitted signal is not finite (``fits``).
    """
    topics = reader.topics()
    out: dict = {
        "file": str(reader.path),
        "files": [str(r.path) for r in reader.files] if isinstance(reader, RunFiles) else [str(reader.path)],
        "complete": reader.complete,
        "message_count": reader.message_count(),
        "topics": {t.topic: {"type": t.type_name, "count": t.message_count} for t in topics},
    }
    if "leg_lengths" in data:
        out["leg_length_mean_m"] = dict(zip(LEG_NAMES, data["leg_length_mean"].tolist()))
    out["vibration_window_s"] = list(data["vibration_window"]) if data.get("vibration_window") else None
    window = data.get("analysed_window")  # the steady vibration, or its middle minute when it is longer
    out["analysed_window_s"] = list(window) if window else None
    steady = data.get("window", {})
    if window and steady.get("vib_t") is not None and steady["vib_t"].size:
        out["vibration"] = {
            n: dict(zip(("amplitude_m", "frequency_hz"), dominant_sinusoid(steady["vib_t"], steady["vib"][:, i])))
            for i, n in enumerate(VIB_NAMES)
        }
    frequency = float(np.median([v["frequency_hz"] for v in out["vibration"].values()])) \
        if out.get("vibration") else None
    origin = data.get("time_origin_s", 0.0)  # the plots' time 0, as header-stamp time (s)
    if "pose_xyz" in data and window and frequency:
        # the run summary's computation (analysis.vibration_figures.platform_vibration) over this window
        line = platform_vibration(signals, window[0] + origin, window[1] + origin, frequency)
        direction = line["direction"] * (1 if line["direction"][np.argmax(np.abs(line["direction"]))] > 0 else -1)
        out["platform"] = {
            "mean_position_m": steady["pose"].mean(axis=0).tolist(),
            "frequency_hz": frequency,
            "vibration_direction": direction.tolist(),
            "vibration_amplitude_m": line["amplitude_m"],
            "off_axis_ratio": line["off_axis_ratio"],
        }
    if "est" in data and "force" in data:
        # the run summary's computation (analysis.vibration_figures.leg_force_error): over the whole run (as the
        # recording streamed past: report_data), and over the steady vibration relative to the fitted amplitude
        whole = data.get("force_error")
        if whole is not None:
            out["force_error_rms_n"] = dict(zip(LEG_NAMES, whole["rms_error_n"].tolist()))
        during = leg_force_error(robot, signals, window[0] + origin, window[1] + origin, frequency) \
            if window and frequency else None
        if during is not None:
            out["force_error_rms_n_vibration"] = dict(zip(LEG_NAMES, during["rms_error_n"].tolist()))
            out["force_error_worst_leg_relative_vibration"] = during["worst_leg_relative"]
    if "wrench_applied" in data and "wrench_estimated" in data:
        ta, te = np.round(data["wrench_applied_t"], 6), np.round(data["wrench_estimated_t"], 6)
        _, ia, ie = np.intersect1d(ta, te, return_indices=True)
        err = data["wrench_estimated"][ie] - data["wrench_applied"][ia]

        def rms(part):
            return float(np.sqrt((np.linalg.norm(err[:, part], axis=1) ** 2).mean())) if len(err) else None

        out["tissue_wrench"] = {
            "peak_applied_force_n": float(np.linalg.norm(data["wrench_applied"][:, :3], axis=1).max()),
            "peak_applied_moment_nm": float(np.linalg.norm(data["wrench_applied"][:, 3:], axis=1).max()),
            "rms_force_error_n": rms(slice(0, 3)), "rms_moment_error_nm": rms(slice(3, 6)), "samples": int(len(err)),
        }
    if data.get("guard_trips"):
        out["guard_trips"] = data["guard_trips"]
    out["events"] = data["events"]
    return out


def markdown(summary: dict, plots: list[str]) -> str:
    """Human-readable summary.

    Args:
        summary: the JSON summary (``summarize``).
        plots: the PNG file names to embed.

    Returns:
        The summary as markdown text (tables of topics, legs and events; plots as images).
    """
    lines = [f"# Run report: {Path(summary['file']).name}", ""]
    lines += [f"- complete file: {summary['complete']}", f"- messages: {summary['message_count']}", ""]
    lines += ["| topic | type | messages |", "|---|---|---|"]
    lines += [f"| {k} | {v['type']} | {v['count']} |" for k, v in summary["topics"].items()]
    if summary.get("vibration_window_s"):
        a, b = summary["vibration_window_s"]
        c, d = summary["analysed_window_s"]
        over = "it" if (a, b) == (c, d) else f"its middle, {c:.2f} s to {d:.2f} s"
        lines += ["", f"Steady vibration from {a:.2f} s to {b:.2f} s (ramps excluded); figures below are over {over}."]
    if "vibration" in summary:
        lines += ["", "| leg | mean length (m) | vib amplitude (m) | frequency (Hz) |", "|---|---|---|---|"]
        for i, (_n, v) in enumerate(summary["vibration"].items()):
            mean = summary.get("leg_length_mean_m", {}).get(LEG_NAMES[i], float("nan"))
            lines.append(f"| {i + 1} | {mean:.6f} | {v['amplitude_m']:.3e} | {v['frequency_hz']:.4f} |")
    if "platform" in summary:
        p = summary["platform"]
        d = ", ".join(f"{x:.4f}" for x in p["vibration_direction"])
        lines += ["", f"Platform vibration at {p['frequency_hz']:.4f} Hz: direction [{d}], amplitude "
                  f"{p['vibration_amplitude_m']:.3e} m, off-axis ratio {p['off_axis_ratio']:.2e}"]
    if "force_error_rms_n" in summary:
        lines += ["", "Leg force estimate vs measured, RMS error (N): "
                  + ", ".join(f"{k} {v:.3f}" for k, v in summary["force_error_rms_n"].items())]
    if "force_error_rms_n_vibration" in summary:
        lines += ["", "During the steady vibration, RMS error (N): "
                  + ", ".join(f"{k} {v:.4f}" for k, v in summary["force_error_rms_n_vibration"].items())]
    if "tissue_wrench" in summary:
        w = summary["tissue_wrench"]
        lines += ["", f"Soft tissue: peak applied {w['peak_applied_force_n']:.1f} N, "
                  f"{w['peak_applied_moment_nm']:.2f} N m; external-wrench estimate vs applied over the whole run, "
                  f"RMS error {w['rms_force_error_n']:.3f} N, {w['rms_moment_error_nm']:.4f} N m "
                  f"({w['samples']} states)"]
    for trip in summary.get("guard_trips", []):
        lines += ["", f"Force guard tripped at {trip['t_s']:.3f} s: {trip['message']}"]
    if summary["events"]:
        lines += ["", "| t (s) | source | level | event |", "|---|---|---|---|"]
        lines += [f"| {e['t_s']:.3f} | {e['source']} | {e['level']} | {e['text']} |" for e in summary["events"]]
    lines += ["", *[f"![{p}]({p})" for p in plots], ""]
    return "\n".join(lines)


def write_report(mcap_path: str | Path, out_dir: str | Path, allow_truncated: bool = False,
                 robot: Robot | None = None) -> dict:
    """Write summary.json, summary.md and the PNGs into ``out_dir``; returns the summary. A report that fails
    writes nothing there (its figures are drawn aside and moved in at the end).

    Args:
        mcap_path: a .mcap or a bag directory.
        out_dir: the output directory (created if missing).
        allow_truncated: accept a truncated (crash) file.
        robot: the robot; None loads config/robot.yaml.

    Returns:
        The JSON summary (``summarize``) with "plots": the PNG file names.

    Raises:
        McapFileError: before anything is written, for a missing, empty, foreign, corrupted (a CRC or a
            record that fails its check: ``mcap_log.integrity``) or, unless ``allow_truncated``, truncated file.
        ConfigError: ``robot`` is None and config/robot.yaml cannot be loaded.
        ValueError, InvalidInputError: as ``summarize``.
    """
    with PlotPool() as pool:  # its workers get ready to draw while the run is read
        reader = open_run(mcap_path, allow_truncated=allow_truncated, verify=True)
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        robot = robot or load_robot()
        data, signals = report_data(reader, robot)
        data["events"] = _events(reader, data["time_origin_ns"])
        # figures are drawn into a staging folder and moved into out_dir only once the whole report succeeded:
        # a report that fails leaves out_dir as it was (no figures of a report whose summary was never written)
        staging = Path(tempfile.mkdtemp(prefix=".report-", dir=out))
        try:
            pool.start(data, staging)
            summary = summarize(reader, data, signals, robot)
            plots = pool.finish(summary)
            summary["plots"] = plots
            for name in plots:
                os.replace(staging / name, out / name)
        finally:
            shutil.rmtree(staging, ignore_errors=True)
    write_text_whole(out / "summary.json", json.dumps(summary, indent=2))
    write_text_whole(out / "summary.md", markdown(summary, plots))
    return summary
