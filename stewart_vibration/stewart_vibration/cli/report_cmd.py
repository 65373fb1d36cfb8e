"""``stewart-vibration report RUN --out DIR``: summary (JSON, markdown) and PNG plots of a run.

RUN is a .mcap or a run folder (rosbag2 bag directory: every .mcap in it, in time order, e.g. one per
recorder start). Every file's CRCs and records are checked first (``mcap_log.integrity``). A missing,
empty, non-MCAP, corrupted or truncated file is refused with one line and exit 2
(``--allow-truncated`` reports what a cut file holds; ``mcap-recover`` rebuilds it).
"""

from __future__ import annotations

from ..analysis.run_report import write_report
from ..kinematics.robot_config import load_robot
from .arguments import refuse_special_file


def register(subparsers) -> None:
    """Add the ``report`` subcommand to ``subparsers``."""
    p = subparsers.add_parser("report", help="summary and plots of a recorded MCAP run")
    p.add_argument("mcap", metavar="RUN", help="the run's .mcap file or its folder (rosbag2 bag directory)")
    p.add_argument("--out", required=True, help="output directory (created)")
    p.add_argument("--allow-truncated", action="store_true",
                   help="report on a file cut short by a crash (whole chunks only) instead of refusing it")
    p.set_defaults(func=run)


def run(args) -> int:
    """``report``: write summary.json, summary.md and the PNG plots of a run to ``--out``; returns 0.

    Raises McapFileError if RUN is missing, empty, not an MCAP, corrupted, or truncated without --allow-truncated;
    InvalidInputError if it is a FIFO or a device; ConfigError for a bad --robot file.
    """
    refuse_special_file(args.mcap, "RUN")
    summary = write_report(args.mcap, args.out, allow_truncated=args.allow_truncated, robot=load_robot(args.robot))
    print(f"report: {summary['message_count']} messages, {len(summary['topics'])} topics; "
          f"wrote summary.json, summary.md and {len(summary['plots'])} plots to {args.out}")
    return 0
