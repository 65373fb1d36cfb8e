"""What the recorder reports about its recording: the /diagnostics status while it runs and the counts of a
finished file (pure; the recorder node publishes and prints them)."""

from __future__ import annotations

from pathlib import Path

from ..messages.stream_health import SequenceGaps
from .writer import WriteFailure, WriterStats

OK, WARN, ERROR = "ok", "warn", "error"


def recording_status(path: Path | None, stats: WriterStats | None, fault: tuple[str, str] | None,
                     gaps: SequenceGaps | None) -> tuple[str, str, dict]:
    """(severity OK / WARN / ERROR, message, key values) of the recorder: recording ``path`` (None: not recording,
    ``stats`` then None), or its write failure ``fault`` (errno name, reason), with the counters; WARN once
    messages were dropped (queue full) or lost before they reached the recorder (``gaps``: None when not
    counted)."""
    per_topic = gaps.per_topic() if gaps else {}
    lost = sum(per_topic.values())
    values: dict = {"lost": lost, "lost_topics": ",".join(f"{t}:{n}" for t, n in sorted(per_topic.items())),
                    "fault": "write_failed" if fault else "", "fault_code": fault[0] if fault else "",
                    "fault_reason": fault[1] if fault else ""}
    if gaps is not None:
        values["sequence_gaps"] = gaps.total
    if path is None or stats is None:
        severity, message = (ERROR, f"recording failed: {fault[1]}") if fault else (OK, "not recording")
        return severity, message, {"path": "", **values}
    if fault:
        severity, message = ERROR, f"recording failed: {fault[1]}; nothing is recorded since"
    else:
        severity = WARN if stats.dropped or lost else OK
        message = f"recording {path}" + (f"; {stats.dropped} messages dropped" if stats.dropped else "") \
            + (f"; {lost} samples lost before they reached the recorder" if lost else "")
    return severity, message, {"path": str(path), "received": stats.received, "written": stats.written,
                               "dropped": stats.dropped, **values}


def finished_report(path: Path, stats: WriterStats, failure: WriteFailure | None, gaps: SequenceGaps | None,
                    stopped_at_s: float, metadata_yaml: Path | None) -> dict:
    """The counts of a finished recording, as the recorder prints and answers them (JSON-able): its file, the
    recorder's clock when it was finished (sim s with use_sim_time: what it had received by then), its
    metadata.yaml, the writer's counters, the samples lost before they reached the recorder (``gaps``: None when
    not counted) and the write failure that cut it, if any."""
    return {
        "path": str(path),
        "stopped_at_s": stopped_at_s,
        "metadata_yaml": str(metadata_yaml) if metadata_yaml else None,
        "received": stats.received,
        "written": stats.written,
        "dropped": stats.dropped,
        "max_backlog": stats.max_backlog,
        "per_topic": dict(stats.per_topic),
        "lost": gaps.total if gaps else 0,
        "lost_per_topic": gaps.per_topic() if gaps else {},
        "sequence_gaps": gaps.per_topic() if gaps else None,
        "failure": {"code": failure.code, "reason": failure.reason, "good_bytes": failure.good_bytes,
                    "lost_after_failure": stats.lost_after_failure} if failure else None,
    }
