"""Checks of single fields of received messages (pure): frame ids, strings, numbers written as text.

Every check returns the value or raises ``MalformedMessageError`` (kind and field named). They are the
one place the suite's readers decide what a well-formed field is:

- a frame id is ``base`` or empty (documented as base), nothing else -- also not ``base\\0x``;
- a string holds no NUL or other control character (tab and newline aside), no U+FFFD (what rclpy
  puts for bytes that are not UTF-8) and at most MAX_TEXT characters;
- a number written as text is plain ASCII decimal (``-1.5e-3``; no ``nan``, ``inf``, ``1_0``, spaces or
  other digits) and finite; an integer is ASCII digits with an optional sign.
"""

from __future__ import annotations

import math
import re

from ..errors import MalformedMessageError

BASE_FRAME = "base"
PLATFORM_FRAME = "platform"  # the moving platform's frame (its sensors: platform/imu)
MAX_TEXT = 65536  # characters of one string field (the suite's longest, a status message, is ~1 kB)
_DECIMAL = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?", re.ASCII)
_INTEGER = re.compile(r"[+-]?\d+", re.ASCII)
_BAD_CHARACTERS = re.compile(r"[\x00-\x08\x0b-\x1f\x7f\ufffd]")
_MAX_NUMBER_TEXT = 64  # characters: a longer "number" is no number this suite writes (and int() of it is slow)


def check_frame(frame_id, what: str) -> str:
    """``frame_id`` if it is ``base`` or empty (meaning base); MalformedMessageError (kind "frame") otherwise.

    Args:
        frame_id: the header's frame_id, as received (for raw CDR: with any bytes after a NUL).
        what: the input, for the message (e.g. "target pose").

    Returns:
        The frame id.
    """
    if frame_id not in ("", BASE_FRAME) or not isinstance(frame_id, str):
        raise MalformedMessageError(f"{what}: frame_id {_shown(frame_id)} is not supported; poses must be in "
                                    f"'{BASE_FRAME}' (or empty, meaning '{BASE_FRAME}')", field="frame_id",
                                    kind="frame")
    return frame_id


def check_text(text, field: str, max_length: int = MAX_TEXT) -> str:
    """``text`` if it is a str without NUL, control characters (tab and newline allowed) or U+FFFD and at most
    ``max_length`` characters; MalformedMessageError (kind "text" or "type") otherwise."""
    if not isinstance(text, str):
        raise MalformedMessageError(f"{field} must be a string, got {type(text).__name__}", field=field, kind="type")
    if len(text) > max_length:
        raise MalformedMessageError(f"{field} is {len(text)} characters long, at most {max_length}", field=field,
                                    kind="text")
    bad = _BAD_CHARACTERS.search(text)
    if bad:
        raise MalformedMessageError(f"{field} holds the character {bad.group()!r} at {bad.start()} (NUL, control "
                                    "character or bytes that were not UTF-8)", field=field, kind="text")
    return text


def parse_number(text, field: str, low: float = -math.inf, high: float = math.inf) -> float:
    """The finite number written in ``text`` (ASCII decimal), within [low, high]; MalformedMessageError
    (kind "type", "not_finite" or "range") otherwise."""
    if not isinstance(text, str) or len(text) > _MAX_NUMBER_TEXT or not _DECIMAL.fullmatch(text):
        raise MalformedMessageError(f"{field} is not a number: {_shown(text)}", field=field, kind="type")
    return _finite_within(float(text), field, low, high)


def parse_integer(text, field: str, low: int = 0, high: int = 2**53) -> int:
    """The integer written in ``text`` (ASCII digits, optional sign), within [low, high]; MalformedMessageError
    (kind "type" or "range") otherwise."""
    if not isinstance(text, str) or len(text) > _MAX_NUMBER_TEXT or not _INTEGER.fullmatch(text):
        raise MalformedMessageError(f"{field} is not an integer: {_shown(text)}", field=field, kind="type")
    value = int(text)
    if not low <= value <= high:
        raise MalformedMessageError(f"{field} = {value} is outside [{low}, {high}]", field=field, kind="range")
    return value


def check_time(sec, nanosec, field: str) -> tuple[int, int]:
    """(sec, nanosec) of a builtin_interfaces/Time that is a time: sec >= 0 and 0 <= nanosec < 1e9 (rclpy raises
    on a negative one, which kills a sim-time node's clock callback); MalformedMessageError (kind "range")."""
    if not (isinstance(sec, int) and isinstance(nanosec, int) and sec >= 0 and 0 <= nanosec < 1_000_000_000):
        raise MalformedMessageError(f"{field} {sec!r} s {nanosec!r} ns is no time (negative seconds or nanosec "
                                    "outside [0, 1e9))", field=field, kind="range")
    return sec, nanosec


def check_number(value, field: str, low: float = -math.inf, high: float = math.inf) -> float:
    """A numeric field of a typed message (float or int, not bool) as a finite float within [low, high];
    MalformedMessageError otherwise."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise MalformedMessageError(f"{field} must be a number, got {type(value).__name__}", field=field, kind="type")
    return _finite_within(float(value), field, low, high)


def _finite_within(value: float, field: str, low: float, high: float) -> float:
    if not math.isfinite(value):
        raise MalformedMessageError(f"{field} is not finite ({value})", field=field, kind="not_finite")
    if not low <= value <= high:
        raise MalformedMessageError(f"{field} = {value:g} is outside [{low:g}, {high:g}]", field=field, kind="range")
    return value


def _shown(value, limit: int = 40) -> str:
    """``value`` for a message: its repr, cut to ``limit`` characters (a hostile string may be megabytes)."""
    text = repr(value)
    if len(text) <= limit:
        return text
    return f"{text[:limit]}... ({len(value) if hasattr(value, '__len__') else '?'} long)"
