"""Readers of the suite's status messages (pure): DiagnosticStatus on vibration/status,
kinematics/guard_status and /diagnostics, and the planner's start answer.

The one place where a status's text becomes typed values: a reader gets a ``StatusMessage`` (checked
as a whole: level 0..3, every string clean, keys unique, bounded sizes) and asks it for what it needs
through typed accessors (``number``, ``integer``, ``choice``, ``numbers``) or one of the typed readers
(``vibration_report``, ``guard_status``, ``recorder_files``, ``emulator_rejections``,
``planner_settings``). Each returns a value or raises
``MalformedMessageError``; a caller counts and ignores what raised (``MalformedCounter``) and goes on
with its last good state. When the status topics become typed messages, this module is what changes.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from ..emulation.vibration_status import VibrationReport
from ..errors import InvalidInputError, MalformedMessageError
from ..vibration.settings import STREAM_KEYS
from .cdr import DiagnosticStatusData, decode_diagnostic_array, decode_diagnostic_status
from .fields import check_number, check_text, parse_integer, parse_number

MAX_VALUES = 512  # key/values of one status (the suite's largest has ~30)
MAX_STATUSES = 1024  # statuses of one DiagnosticArray
LEVEL_NAMES = ("ok", "warn", "error", "stale")  # DiagnosticStatus.OK .. STALE
MAX_PATH = 4096  # characters of a file path in a status (PATH_MAX)
# states of the vibration units (emulation.vibration_status)
VIBRATION_STATES = frozenset({"idle", "pending", "ramping_in", "running", "ramping_out", "stopped", "estopped"})
MAX_AMPLITUDE_UM = 1e6  # a reported unit amplitude beyond 1 m is no measurement
_REQUIRED = object()


@dataclass(frozen=True)
class StatusMessage:
    """A well-formed DiagnosticStatus: level (0 OK, 1 WARN, 2 ERROR, 3 STALE), name ("node: what"), message,
    hardware_id and its values (key -> value, read-only)."""

    level: int
    name: str
    message: str
    hardware_id: str = ""
    values: Mapping[str, str] = field(default_factory=dict)

    @property
    def node(self) -> str:
        """The publishing node's name as the status names it (the part before the first ':')."""
        return self.name.split(":")[0]

    @property
    def level_name(self) -> str:
        """"ok", "warn", "error" or "stale"."""
        return LEVEL_NAMES[self.level]


def checked_status(level, name, message, hardware_id, pairs) -> StatusMessage:
    """A StatusMessage from a status's fields, every one checked.

    Args:
        level: the level (an int, or the one-byte bytes rclpy gives), 0..3.
        name, message, hardware_id: its strings (no NUL or control characters, at most MAX_TEXT each).
        pairs: its (key, value) string pairs; keys non-empty and unique, at most MAX_VALUES.

    Returns:
        The StatusMessage.

    Raises:
        MalformedMessageError: the first field that is not well formed.
    """
    if isinstance(level, (bytes, bytearray)) and len(level) == 1:
        level = level[0]
    if isinstance(level, bool) or not isinstance(level, int) or not 0 <= level < len(LEVEL_NAMES):
        raise MalformedMessageError(f"level must be 0..3 (OK, WARN, ERROR, STALE), got {level!r}", field="level",
                                    kind="range")
    name, message = check_text(name, "name"), check_text(message, "message")
    hardware_id = check_text(hardware_id, "hardware_id")
    pairs = list(pairs)
    if len(pairs) > MAX_VALUES:
        raise MalformedMessageError(f"{len(pairs)} key/values, at most {MAX_VALUES}", field="values", kind="length")
    values: dict[str, str] = {}
    for key, value in pairs:
        check_text(key, "key", 256)
        if not key or key in values:
            raise MalformedMessageError(f"key {key!r} is empty or repeated", field=key or "key", kind="names")
        values[key] = check_text(value, key)
    return StatusMessage(level, name, message, hardware_id, MappingProxyType(values))


def status_from_data(data: DiagnosticStatusData) -> StatusMessage:
    """A checked StatusMessage of a decoded one (cdr.DiagnosticStatusData)."""
    return checked_status(data.level, data.name, data.message, data.hardware_id, data.values)


def status_from_cdr(data) -> StatusMessage:
    """A checked StatusMessage of raw DiagnosticStatus bytes; MalformedMessageError if they are not one."""
    try:
        decoded = decode_diagnostic_status(data)
    except InvalidInputError as exc:
        raise MalformedMessageError(str(exc)) from None
    return status_from_data(decoded)


def statuses_from_cdr(data) -> tuple[list[StatusMessage], list[MalformedMessageError]]:
    """The well-formed statuses of raw DiagnosticArray bytes and the errors of the others (bytes that are no
    DiagnosticArray at all: no statuses and one error)."""
    try:
        _, _, decoded = decode_diagnostic_array(data)
    except InvalidInputError as exc:
        return [], [MalformedMessageError(str(exc))]
    if len(decoded) > MAX_STATUSES:
        return [], [MalformedMessageError(f"{len(decoded)} statuses, at most {MAX_STATUSES}", field="status",
                                          kind="length")]
    good, bad = [], []
    for status in decoded:
        try:
            good.append(status_from_data(status))
        except MalformedMessageError as exc:
            bad.append(exc)
    return good, bad


def status_from_msg(msg) -> StatusMessage:
    """A checked StatusMessage of a typed diagnostic_msgs/DiagnosticStatus (rclpy has already cut its strings at
    a NUL; prefer raw subscriptions and ``status_from_cdr``)."""
    return checked_status(msg.level, msg.name, msg.message, msg.hardware_id, ((kv.key, kv.value) for kv in msg.values))


# -- accessors ----------------------------------------------------------------------------------------------
def _get(values: Mapping[str, str], key: str, missing=_REQUIRED):
    """``values[key]``; ``missing`` for a missing key when given, else MalformedMessageError."""
    if key in values:
        return values[key]
    if missing is _REQUIRED:
        raise MalformedMessageError(f"{key} is missing", field=key, kind="missing")
    return missing


def number(values: Mapping[str, str], key: str, low: float = -math.inf, high: float = math.inf,
           empty=_REQUIRED, missing=_REQUIRED):
    """The finite number of ``values[key]`` within [low, high]. An empty value gives ``empty`` and a missing
    key ``missing`` when those are given (else MalformedMessageError)."""
    if key not in values:
        return _get(values, key, missing)
    text = values[key]
    if text == "" and empty is not _REQUIRED:
        return empty
    return parse_number(text, key, low, high)


def integer(values: Mapping[str, str], key: str, low: int = 0, high: int = 2**53, missing=_REQUIRED):
    """The integer of ``values[key]`` within [low, high]; ``missing`` for a missing key when given."""
    if key not in values:
        return _get(values, key, missing)
    return parse_integer(values[key], key, low, high)


def choice(values: Mapping[str, str], key: str, choices, missing=_REQUIRED) -> str:
    """``values[key]`` if it is one of ``choices``; ``missing`` for a missing key when given."""
    if key not in values:
        return _get(values, key, missing)
    text = values[key]
    if text not in choices:
        raise MalformedMessageError(f"{key} {text[:40]!r} is not one of {sorted(choices)}", field=key, kind="range")
    return text


def numbers(values: Mapping[str, str], key: str, count: int, low: float = -math.inf,
            high: float = math.inf) -> np.ndarray:
    """The ``count`` comma-separated finite numbers of ``values[key]``, each within [low, high]."""
    parts = _get(values, key).split(",")
    if len(parts) != count:
        raise MalformedMessageError(f"{key} holds {len(parts)} values, expected {count}", field=key, kind="length")
    return np.array([parse_number(p, key, low, high) for p in parts])


# -- vibration/status (hardware emulator) --------------------------------------------------------------------
def vibration_report(status: StatusMessage) -> VibrationReport:
    """The emulator's VibrationReport of a vibration/status (the inverse of ``VibrationReport.as_values``)."""
    return vibration_report_from_values(status.level_name, status.values)


def vibration_report_from_cdr(data) -> VibrationReport:
    """The VibrationReport of a raw vibration/status (what its subscribers read)."""
    return vibration_report(status_from_cdr(data))


def vibration_report_from_values(level: str, values: Mapping[str, str]) -> VibrationReport:
    """The VibrationReport of a vibration/status's key/values (as ``VibrationReport.as_values`` writes them:
    every key present; the times that value writes empty when unknown may be empty).

    Args:
        level: the status level ("ok", "warn", "error" or "stale").
        values: the key/value strings (amplitude_um: 6 values in um, >= 0; times in s; counts >= 0).

    Returns:
        The VibrationReport (amplitude [6] in m, times in s; an empty since / time is 0, an empty
        commanded_until -inf, an empty ramp_start / event_stamp / event_time None).

    Raises:
        MalformedMessageError: a key is missing, a state unknown, a number not a finite number, a count
            not a non-negative integer, an amplitude not 6 values in [0, MAX_AMPLITUDE_UM].
    """
    return VibrationReport(
        state=choice(values, "state", VIBRATION_STATES), level=level, reason=_get(values, "reason"),
        since=number(values, "since_s", empty=0.0), time=number(values, "time_s", empty=0.0),
        amplitude=numbers(values, "amplitude_um", 6, 0.0, MAX_AMPLITUDE_UM) * 1e-6,
        commanded_until=number(values, "commanded_until_s", empty=-math.inf),
        ramp_start=number(values, "ramp_start_s", empty=None), ramp_reason=_get(values, "ramp_reason"),
        event_seq=integer(values, "event_seq"), event=_get(values, "event"),
        event_stamp=number(values, "event_stamp_s", empty=None), event_time=number(values, "event_time_s", empty=None),
        accepted=integer(values, "accepted_windows"), refused=integer(values, "refused_windows"),
        fault=_get(values, "fault"))


# -- /diagnostics of the suite's nodes ----------------------------------------------------------------------
def emulator_rejections(status: StatusMessage) -> int | None:
    """The hardware emulator's count of refused commands (its /diagnostics value ``rejections``), None before
    its first refusal (the value is absent then)."""
    return integer(status.values, "rejections", missing=None)


@dataclass(frozen=True)
class RecorderFiles:
    """The MCAP recorder's files as its /diagnostics names them: the one being written ("" when not
    recording) and the last finished one ("" before the first)."""

    path: str
    last_file: str


def recorder_files(status: StatusMessage) -> RecorderFiles:
    """The RecorderFiles of the MCAP recorder's /diagnostics status (paths at most MAX_PATH characters)."""
    path, last = _get(status.values, "path", ""), _get(status.values, "last_file", "")
    for key, value in (("path", path), ("last_file", last)):
        check_text(value, key, MAX_PATH)
    return RecorderFiles(path, last)


# -- kinematics/guard_status ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class GuardStatus:
    """kinematics/guard_status: state ("armed" | "tripped"), the trip's limit ("force", "moment",
    "estimates"; "" when armed) and time (s; None when armed), the message and every value (strings)."""

    state: str
    trip_limit: str
    trip_time_s: float | None
    message: str
    values: Mapping[str, str]


def guard_status_from_cdr(data) -> GuardStatus:
    """The GuardStatus of a raw kinematics/guard_status."""
    return guard_status(status_from_cdr(data))


def guard_status(status: StatusMessage) -> GuardStatus:
    """The GuardStatus of a kinematics/guard_status (motion.ForceGuard.status_values)."""
    return guard_status_from_values(status.values, status.message)


def guard_status_from_values(values: Mapping[str, str], message: str = "") -> GuardStatus:
    """The GuardStatus of a kinematics/guard_status's key/values (e.g. as recorded); raises
    MalformedMessageError for an unknown state or trip limit or a trip time that is not a finite number."""
    state = choice(values, "state", ("armed", "tripped"))
    if state == "armed":
        return GuardStatus(state, "", None, message, values)
    return GuardStatus(state, choice(values, "trip_limit", ("force", "moment", "estimates")),
                       number(values, "trip_time_s"), message, values)


# -- the vibration planner's start answer ---------------------------------------------------------------------


def _json(text: str):
    """json.loads refusing NaN / Infinity and nesting bombs: MalformedMessageError."""
    def constant(name):
        raise ValueError(f"{name} is not a JSON number")
    try:
        return json.loads(text, parse_constant=constant)
    except (ValueError, RecursionError) as exc:
        raise MalformedMessageError(f"not JSON: {str(exc)[:80]}", field="settings", kind="type") from None


def planner_settings(values: Mapping[str, object]) -> dict:
    """The vibration planner's streaming parameters as its get_parameters answers them (Python values of each
    name of vibration.settings.STREAM_KEYS), every one a finite number (floats then). The values' plausibility
    is the planner's settings check's business.

    Raises:
        MalformedMessageError: a name missing or a value of the wrong kind.
    """
    return {name: check_number(_get(values, name), name) for name in STREAM_KEYS}  # type: ignore[arg-type]
