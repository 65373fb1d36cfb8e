"""Entry point of ``stewart-vibration``: one subcommand module per job.

Each module in SUBCOMMAND_MODULES has ``register(subparsers)`` which adds its
parser and sets ``func(args) -> int`` (the exit code). Typed errors of the
library (StewartError: bad input, a bad config file, unreachable or singular
pose, unusable MCAP file) and OS errors on files print one ``error: ...`` line
and exit 2; bad argument values are refused by argparse in one line (exit 2).
"""

from __future__ import annotations

import argparse
import importlib
import sys

from ..errors import StewartError

ROBOT_HELP = "robot YAML (default: config/robot.yaml); every node of a run reads the same file"
SUBCOMMAND_MODULES = [
    "stewart_vibration.cli.report_cmd",
    "stewart_vibration.cli.kinematics_cmd",
    "stewart_vibration.cli.scenario_cmd",
    "stewart_vibration.cli.run_cmd",
    "stewart_vibration.cli.paper_cmd",
    "stewart_vibration.cli.validate_dynamics_cmd",
    "stewart_vibration.cli.mcap_recover_cmd",
    "stewart_vibration.cli.topic_rate_cmd",
    "stewart_vibration.cli.calibrate_cmd",
]


class OneLineParser(argparse.ArgumentParser):
    """An argparse parser whose refusal of an argument is one line on stderr (exit 2), without the usage block."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {' '.join(message.split())} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """The ``stewart-vibration`` argparse parser with every subcommand of SUBCOMMAND_MODULES registered."""
    parser = OneLineParser(
        prog="stewart-vibration",
        description="6-UPS tibia robot: kinematics, vibration and dynamics tools (SI units).",
    )
    parser.add_argument("--robot", help=ROBOT_HELP)
    subparsers = parser.add_subparsers(dest="command", required=True)
    for name in SUBCOMMAND_MODULES:
        importlib.import_module(name).register(subparsers)
    for subparser in subparsers.choices.values():  # also after the subcommand (./tools/main --robot r.yaml)
        subparser.add_argument("--robot", default=argparse.SUPPRESS, help=ROBOT_HELP)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line ``argv`` (default: sys.argv); returns the exit code.

    A StewartError or OSError prints one ``error: ...`` line and returns 2 instead of raising.
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except StewartError as exc:
        print(f"error: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # a file or folder the command cannot read or write: one line, no traceback
        where = f": {exc.filename}" if exc.filename else ""
        print(f"error: {exc.strerror or exc}{where}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
