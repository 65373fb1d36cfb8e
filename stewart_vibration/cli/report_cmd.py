"""``stewart-vibration report RUN.mcap --out DIR``: summary (JSON, markdown) and PNG plots of a run."""

from __future__ import annotations

from ..mcap_log.run_report import write_report


def register(subparsers) -> None:
    p = subparsers.add_parser("report", help="summary and plots of a recorded MCAP run")
    p.add_argument("mcap", help="the run's .mcap file")
    p.add_argument("--out", required=True, help="output directory (created)")
    p.set_defaults(func=run)


def run(args) -> int:
    summary = write_report(args.mcap, args.out)
    print(f"report: {summary['message_count']} messages, {len(summary['topics'])} topics; "
          f"wrote summary.json, summary.md and {len(summary['plots'])} plots to {args.out}")
    return 0
