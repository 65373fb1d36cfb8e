"""What a suite run's recording covers and how its streams held up (pure: no rclpy).

The gaps in legs/joint_states (the 500 Hz stream every state of the robot is on) over the run's span, within a
file or between files, cut files, the gap each restarted node left in its 500 Hz output, and per 500 Hz topic the
messages against the joint states and what each node reported about its input (received, lost, lag). Times in
sim s, lags in ms.
"""

from __future__ import annotations

import numpy as np

from ..errors import MalformedMessageError
from ..messages.status_values import integer, number, vibration_report_from_cdr

GAP_FACTOR = 1.5  # a step between states longer than this many periods is a gap
MAX_GAPS_LISTED = 100  # gaps listed one by one (all are counted)
SPAN_START_MARGIN_S = 0.5  # the recorder is seen subscribed a moment before its subscription is matched
SPAN_END_MARGIN_S = 0.1  # the runner's clock at the recorder's stop may be this much ahead of its last state
# the 500 Hz output a node's restart interrupts (the recorder's: the recording itself)
NODE_OUTPUTS = {"hardware_emulator": "legs/joint_states", "kinematics": "platform/pose_estimate",
                "leg_force_estimator": "legs/force_estimate", "mcap_recorder": "legs/joint_states"}


def stream_gaps(stamps_ns, lo: float | None = None, hi: float | None = None) -> dict:
    """The gaps of one uniformly stamped stream over [lo, hi] (s; default its own first and last stamp).

    Args:
        stamps_ns: stamps [n] (ns), any order.
        lo: start of the span judged (s); a stream that starts later has a gap at the head.
        hi: end of the span judged (s); one that ends earlier has a gap at the tail.

    Returns:
        {"period_s": median step, "span_s": [lo, hi], "expected": samples the span holds at that period,
        "recorded": samples in it, "missing": samples not there, "gaps": [{"start_s", "end_s", "missing"}]
        (start/end: the last stamp before and the first after, or the span's edge; the first
        MAX_GAPS_LISTED), "gap_count": every gap}; with fewer than two stamps the period is NaN and nothing
        is expected.
    """
    t = np.sort(np.asarray(stamps_ns, dtype=np.int64)) / 1e9
    if t.size < 2:
        return {"period_s": float("nan"), "span_s": [lo, hi], "expected": 0, "recorded": int(t.size), "missing": 0,
                "gaps": [], "gap_count": 0}
    period = float(np.median(np.diff(t)))
    lo = float(t[0]) if lo is None else float(lo)
    hi = float(t[-1]) if hi is None else float(hi)
    inside = t[(t >= lo - 0.5 * period) & (t <= hi + 0.5 * period)]
    edges = np.concatenate([[lo - period], inside, [hi + period]])
    steps = np.diff(edges)
    missing = np.maximum(np.rint(steps / period).astype(int) - 1, 0)
    where = np.flatnonzero(steps > GAP_FACTOR * period)
    gaps = [{"start_s": float(max(edges[i], lo)), "end_s": float(min(edges[i + 1], hi)), "missing": int(missing[i])}
            for i in where[:MAX_GAPS_LISTED]]
    expected = int(round((hi - lo) / period)) + 1 if hi >= lo else 0
    return {"period_s": period, "span_s": [lo, hi], "expected": expected, "recorded": int(inside.size),
            "missing": int(missing[where].sum()), "gaps": gaps, "gap_count": int(where.size)}


def recording_coverage(signals: dict, span: tuple[float, float] | None = None) -> dict:
    """What the recording covers of the run: every file, and the gaps in legs/joint_states (the 500 Hz
    stream every state of the robot is on) over the run's span, within a file or between files.

    Args:
        signals: from ``load_signals`` (stream_stamps, files).
        span: (start, end) (sim s) the run was recorded over, as the runner saw it (from the recorder's
            readiness to its stop; judged from SPAN_START_MARGIN_S after the one to SPAN_END_MARGIN_S before
            the other); None: from the first to the last recorded state.

    Returns:
        ``stream_gaps`` of the joint states plus "files", "ratio" (recorded / expected; 0 if nothing) and
        "clock": ``stream_gaps`` of the recorded /clock values (None with fewer than two): its ticks the
        recording lost (printed; no figure needs them).
    """
    lo, hi = (None, None) if span is None else (span[0] + SPAN_START_MARGIN_S, span[1] - SPAN_END_MARGIN_S)
    out = stream_gaps(signals["stream_stamps"]["legs/joint_states"], lo, hi)
    out["files"] = signals.get("files", [])
    clock = np.asarray(signals.get("clock", np.empty(0)), float)
    out["clock"] = stream_gaps(np.rint(clock * 1e9).astype(np.int64), lo, hi) if clock.size > 1 else None
    out["ratio"] = out["recorded"] / out["expected"] if out["expected"] else 0.0
    return out


def restart_gaps(signals: dict, restarts: list[dict]) -> list[dict]:
    """The gap each restarted node left in its 500 Hz output (``NODE_OUTPUTS``).

    Args:
        signals: from ``load_signals`` (stream_stamps).
        restarts: {"node", "exit_code", "sim_time_s" (when its exit was seen, or None)} per restart.

    Returns:
        Per restart: the restart's keys plus "stream" (None for a node without such an output) and
        "gap_s": (its last stamp before the exit was seen, its first stamp after) (s), the end None when the
        output never came back; None when nothing can be measured.
    """
    out = []
    for restart in restarts:
        row = dict(restart, stream=NODE_OUTPUTS.get(restart["node"]), gap_s=None)
        when = restart.get("sim_time_s")
        stamps = signals["stream_stamps"].get(row["stream"]) if row["stream"] else None
        if stamps is not None and stamps.size and when is not None:
            t = np.sort(stamps) / 1e9
            before, after = t[t <= when], t[t > when]  # the node died before its exit was seen at ``when``
            if before.size:
                row["gap_s"] = (float(before[-1]), float(after[0]) if after.size else None)
        out.append(row)
    return out


def stream_summary(signals: dict) -> dict:
    """Per 500 Hz topic: messages and their ratio to legs/joint_states (every state should give one pose
    estimate, one force estimate and one wrench estimate); and what each node reported about its input
    (received, lost, processed, lag) in its last diagnostics.

    Args:
        signals: from ``load_signals`` (stream_counts, node_diagnostics, vibration_status).

    Returns:
        {"topics": {topic: {"count", "ratio"}}, "nodes": {node: {"received", "lost", "processed",
        "lag_p50_ms", "lag_p99_ms", "level", "message"}}, "worst_ratio": the lowest ratio of the derived
        streams (0.0 if none), "lost": states lost over all nodes, "windows": {"accepted", "refused",
        "refusals"} (of the last well-formed vibration status), "malformed_statuses": the recorded statuses
        that could not be read (messages.status_values), left out, "untyped_statuses": {topic: count} of
        statuses recorded in another type (a log from before the typed statuses), not read, "undecodable":
        {topic: count} of the recorded messages that could not be decoded, left out of every figure}.
    """
    counts = signals["stream_counts"]
    base = max(counts.get("legs/joint_states", 0), 1)
    topics = {topic: {"count": int(n), "ratio": n / base} for topic, n in counts.items()}
    nodes, malformed = {}, []
    for name, (level, message, values) in signals.get("node_diagnostics", {}).items():
        if "states_received" in values:
            try:
                nodes[name.split(":")[0]] = {
                    "received": integer(values, "states_received"), "lost": integer(values, "states_lost", missing=0),
                    "processed": integer(values, "states_processed", missing=0),
                    "lag_p50_ms": number(values, "states_lag_p50_ms", missing=0.0),
                    "lag_p99_ms": number(values, "states_lag_p99_ms", missing=0.0), "level": level, "message": message}
            except MalformedMessageError as exc:  # a status not of the node it names (recorded as it came)
                malformed.append(f"/diagnostics {name[:60]!r}: {exc}")
    reports = []
    for data in signals.get("vibration_status") or []:
        try:
            reports.append(vibration_report_from_cdr(data))
        except MalformedMessageError as exc:
            malformed.append(f"vibration/status: {exc}")
    windows = {"accepted": reports[-1].accepted if reports else 0, "refused": reports[-1].refused if reports else 0,
               "refusals": sorted({f"{r.event_outcome}: {r.event_reason}" for r in reports if r.event == "refused"})}
    derived = [topics[t]["ratio"] for t in ("platform/pose_estimate", "legs/force_estimate",
                                            "platform/external_wrench_estimate") if t in topics]
    return {"topics": topics, "nodes": nodes, "worst_ratio": min(derived) if derived else 0.0,
            "lost": sum(n["lost"] for n in nodes.values()), "windows": windows, "malformed_statuses": malformed,
            "untyped_statuses": dict(signals.get("untyped_statuses") or {}),
            "undecodable": dict(signals.get("undecodable") or {})}


def recording_problems(coverage: dict, restarts: list[dict]) -> list[str]:
    """What the recording misses, one problem line each: every gap in the states (in a file, between files,
    at the head or tail of the run's span), every cut file, every restarted node with the gap it left.

    Args:
        coverage: ``recording_coverage``.
        restarts: ``restart_gaps``.

    Returns:
        Problem lines (empty: the recording covers the run).
    """
    problems = []
    for gap in coverage["gaps"]:
        problems.append(f"the recording has a gap from {gap['start_s']:.3f} s to {gap['end_s']:.3f} s "
                        f"({gap['end_s'] - gap['start_s']:.3f} s, {gap['missing']} states not recorded)")
    if coverage.get("gap_count", 0) > len(coverage["gaps"]):
        problems.append(f"... and {coverage['gap_count'] - len(coverage['gaps'])} more gaps "
                        f"({coverage['missing']} states not recorded in all)")
    for f in coverage["files"]:
        if not f["complete"]:
            problems.append(f"{f['file']} was cut short (no summary; its whole chunks are analysed; rebuild it "
                            "with stewart-vibration mcap-recover)")
    for r in restarts:
        gap = r.get("gap_s")
        what = (f"; its {r['stream']} stopped at {gap[0]:.3f} s and "
                + (f"resumed at {gap[1]:.3f} s ({gap[1] - gap[0]:.3f} s gap)" if gap[1] is not None
                   else "never resumed") if gap else
                f"; {'no 500 Hz output to measure its gap' if r['stream'] is None else 'its gap cannot be measured'}")
        when = f" at {r['sim_time_s']:.3f} s" if r.get("sim_time_s") is not None else ""
        problems.append(f"{r['node']} exited with code {r['exit_code']}{when} and was restarted{what}")
    return problems


def recording_lines(summary: dict) -> list[str]:
    """The run summary's lines on what the recording covers and on the limits (printed with the figures).

    Args:
        summary: the run summary ("recording": ``recording_coverage``, "limits": ``limit_summary``).

    Returns:
        Text lines.
    """
    lines = []
    rec = summary.get("recording")
    if rec:
        lo, hi = rec["span_s"]
        files = ", ".join(f"{f['file']} ({f['states']} states{'' if f['complete'] else ', cut'})" for f in rec["files"])
        span = f" over {lo:.3f}..{hi:.3f} s of sim time" if lo is not None and hi is not None else ""
        lines.append(f"recording: {len(rec['files'])} file(s): {files}; legs/joint_states {rec['recorded']} of "
                     f"{rec['expected']} states{span} ({rec['ratio'] * 100:.2f} %), "
                     f"{rec.get('gap_count', len(rec['gaps']))} gap(s)")
        clock = rec.get("clock")
        if clock and clock["missing"]:
            lines.append(f"  /clock: {clock['missing']} of {clock['expected']} ticks not recorded "
                         f"({clock['gap_count']} gaps)")
    if summary.get("limits"):
        lines.append("limits over the recorded states (independent check of the true joint states and "
                     "ground_truth/platform_pose):")
        lines += [f"  {f['line']}" for f in summary["limits"]]
    return lines
