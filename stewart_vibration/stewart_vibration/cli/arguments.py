"""argparse types that refuse bad numbers with a reason (argparse then exits 2 with one error line)."""

from __future__ import annotations

import argparse
import math

from ..errors import InvalidInputError
from ..runtime.suite import namespace_reason
from ..safe_yaml import special_file_reason


def _number(text: str, kind=float):
    try:
        value = kind(text)
    except (ValueError, OverflowError):
        what = "number" if kind is float else "whole number"
        raise argparse.ArgumentTypeError(f"{text!r} is not a {what}") from None
    if kind is float and not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


def finite_float(text: str) -> float:
    """Any finite number (no nan / inf)."""
    return _number(text)


def positive_float(text: str) -> float:
    """A finite number > 0."""
    value = _number(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return value


def nonnegative_float(text: str) -> float:
    """A finite number >= 0."""
    value = _number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text}")
    return value


def float_in(low: float, high: float, unit: str = ""):
    """An argparse type: a finite number in [low, high] (``unit`` for the message)."""

    def parse(text: str) -> float:
        value = _number(text)
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"must be in [{low:g}, {high:g}]{' ' + unit if unit else ''}, got {text}")
        return value

    return parse


def int_in(low: int, high: int):
    """An argparse type: a whole number in [low, high]."""

    def parse(text: str) -> int:
        value = _number(text, int)
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"must be a whole number in {low}..{high}, got {text}")
        return value

    return parse


def ros_namespace(text: str) -> str:
    """A ROS namespace a run can use (``runtime.suite.namespace_reason``)."""
    reason = namespace_reason(text)
    if reason:
        raise argparse.ArgumentTypeError(f"not a ROS namespace: {reason}")
    return text


def refuse_special_file(path, what: str) -> None:
    """InvalidInputError if ``path`` exists and is a FIFO, a device or a socket: a command would block on it or
    read it forever (a missing path is for the command to say)."""
    kind = special_file_reason(path)
    if kind:
        raise InvalidInputError(f"{what} {path}: {kind}, not a regular file or folder")
