"""``stewart-vibration mcap-recover IN [OUT]``: rebuild a complete, indexed MCAP from a file cut by a crash.

IN is a .mcap, or a run folder holding one cut .mcap. OUT (default: IN's name
with ``.recovered.mcap``, beside it; a directory: the same name inside it) gets
every whole chunk and message of IN in rosbag2's layout, and its folder gets a
``metadata.yaml`` so it opens as a rosbag2 bag directory.

Exit codes: 0 rebuilt, IN was complete (nothing lost); 1 rebuilt, IN was cut
or damaged (what was lost is printed); 2 nothing written (IN missing, empty,
not an MCAP, no whole message; OUT exists without --force; bad arguments).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import cast

from ..mcap_log.bag_metadata import METADATA_FILE, read_metadata_yaml
from ..mcap_log.files import McapFileError, read_layout
from ..mcap_log.recover import RecoveryReport, recover
from .arguments import refuse_special_file
from .output import format_table

SUFFIX = ".recovered.mcap"


def register(subparsers) -> None:
    """Add the ``mcap-recover`` subcommand to ``subparsers``."""
    p = subparsers.add_parser(
        "mcap-recover",
        help="rebuild a complete, indexed rosbag2 MCAP (+ metadata.yaml) from a file cut by a crash",
        description="Rebuild a complete, indexed rosbag2-layout MCAP from every whole chunk and message of IN "
                    "and write metadata.yaml beside it. Exit 0: IN was complete; 1: IN was cut or damaged "
                    "(rebuilt, losses printed); 2: nothing written.",
    )
    p.add_argument("input", metavar="IN", help="the cut .mcap, or a run folder holding it")
    p.add_argument("output", metavar="OUT", nargs="?",
                   help=f"output .mcap or directory (default: IN with {SUFFIX}, beside it)")
    p.add_argument("--force", action="store_true", help="overwrite OUT if it exists")
    p.add_argument("--no-metadata", action="store_true", help=f"do not write {METADATA_FILE} beside OUT")
    p.add_argument("--json", action="store_true", help="print the recovery report as JSON")
    p.set_defaults(func=run)


def _input_file(path: Path) -> Path:
    """IN itself, or the one cut (else the one) .mcap of a run folder."""
    if not path.exists():
        raise McapFileError(f"{path}: no such file or directory", path=path, kind="missing")
    if not path.is_dir():
        return path
    candidates = sorted(p for p in path.glob("*.mcap") if not p.name.endswith(SUFFIX))
    if not candidates:
        raise McapFileError(f"{path}: no .mcap file in this folder", path=path, kind="missing")
    if len(candidates) == 1:
        return candidates[0]
    cut = [p for p in candidates if p.stat().st_size and not _complete(p)]
    if len(cut) == 1:
        return cut[0]
    names = ", ".join(p.name for p in (cut or candidates))
    raise McapFileError(f"{path}: {len(cut or candidates)} candidate .mcap files ({names}); give one",
                        path=path, kind="bad_bag")


def _complete(path: Path) -> bool:
    try:
        return read_layout(path).footer
    except McapFileError:
        return False


def _output_file(src: Path, output: str | None) -> Path:
    if output is None:
        return src.with_name(src.name[: -len(".mcap")] + SUFFIX if src.name.endswith(".mcap") else src.name + SUFFIX)
    out = Path(output)
    if out.is_dir() or output.endswith(("/", "\\")):
        return out / src.name
    return out


def run(args) -> int:
    """``mcap-recover``: rebuild IN into OUT (+ metadata.yaml) and print what was recovered and lost.

    Returns 0 if IN was complete, 1 if it was cut or damaged. Raises McapFileError (IN missing, empty,
    not an MCAP, ambiguous run folder, or OUT exists without --force) and OSError on unwritable files.
    """
    refuse_special_file(args.input, "IN")
    src = _input_file(Path(args.input))
    out = _output_file(src, args.output)
    refuse_special_file(out, "OUT")
    if out.exists() and not args.force:
        raise McapFileError(f"{out}: exists; give another OUT or --force", path=out, kind="bad_bag")
    previous = _listed_files(out.parent) if not args.no_metadata else None
    report = recover(src, out, write_metadata=not args.no_metadata)
    if args.json:
        print(json.dumps(report.as_dict(), indent=2))
    else:
        print(_text(report, previous))
    return 1 if report.data_lost else 0


def _listed_files(folder: Path) -> list[str] | None:
    try:
        return [str(f) for f in read_metadata_yaml(folder)["relative_file_paths"]]
    except Exception:  # noqa: BLE001 - none, or not readable: it is replaced either way
        return None


def _seconds(ns: int | None) -> str:
    return "?" if ns is None else f"{ns / 1e9:.3f} s"


def _text(r: RecoveryReport, previous: list[str] | None) -> str:
    lay = r.layout
    state = ("complete (footer and summary present)" if r.complete_input
             else f"cut short: {lay.stop_reason}")
    lines = [f"input: {r.source} ({lay.size:,} bytes), {state}"]
    span = (r.end_ns or 0) - (r.start_ns or 0)
    lines.append(f"recovered: {r.messages:,} messages on {len(r.topics)} topics from {r.chunks_read} complete "
                 f"chunks; log time {_seconds(r.start_ns)} .. {_seconds(r.end_ns)} ({span / 1e9:.3f} s)")
    rows = [[t.topic, t.type_name, f"{t.messages:,}"] for t in sorted(r.topics.values(), key=lambda t: t.topic)]
    lines += ["  " + line for line in format_table(["topic", "type", "messages"], rows).splitlines()]
    lost = []
    if lay.bytes_unread:
        lost.append(f"{lay.bytes_unread:,} bytes at the end were not whole records (read {lay.good_end:,} of "
                    f"{lay.size:,})")
    if (p := r.partial_chunk) is not None:
        lost.append(f"the chunk cut by the crash (log time {_seconds(p.start_ns)} .. {_seconds(p.end_ns)}, "
                    f"{p.bytes_present:,} of {p.bytes_declared:,} bytes on disk): {p.salvaged} of its messages "
                    "salvaged, the rest lost")
    lost += [f"skipped damaged {c}" for c in r.corrupt_chunks]
    if r.orphan_messages:
        lost.append(f"{r.orphan_messages} messages whose channel or schema record was lost")
    if r.not_cdr_messages:
        lost.append(f"{r.not_cdr_messages} messages skipped: not cdr-encoded (a rosbag2 bag holds cdr only)")
    if not r.complete_input:
        lost.append("messages the writer still held in memory at the crash never reached the file "
                    "(at most one flush period, recorder parameter flush_period_s)")
    lines.append("lost: " + ("nothing" if not lost else "\n  " + "\n  ".join(lost)))
    wrote = f"wrote: {r.output}"
    if r.metadata_yaml is not None:
        wrote += f" and {r.metadata_yaml} (the folder opens as a rosbag2 bag directory)"
        if previous and previous != [cast(Path, r.output).name]:  # metadata is written only with an output
            wrote += f"; it replaces a {METADATA_FILE} that listed {', '.join(previous)}"
    lines.append(wrote)
    return "\n".join(lines)
