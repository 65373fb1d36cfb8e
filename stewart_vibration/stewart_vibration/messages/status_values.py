"""Readers of the suite's status messages (pure): VibrationUnitsStatus on vibration/status and ForceGuardStatus on
kinematics/guard_status (raw CDR, every field checked), DiagnosticStatus on /diagnostics, and the planner's
streaming parameters.

A /diagnostics reader gets a ``StatusMessage`` (checked as a whole: level 0..3, every string clean, keys
unique, bounded sizes) and asks it for what it needs through typed accessors (``number``, ``integer``,
``choice``, ``numbers``) or one of the typed readers (``recorder_files``, ``emulator_rejections``). The two
status topics decode to their core values (``vibration_report_from_cdr``: an emulation.vibration_status
VibrationReport; ``guard_status_from_cdr``: a motion.guard_status GuardStatus). Each returns a value or raises
``MalformedMessageError``; a caller counts and ignores what raised (``MalformedCounter``) and goes on with its
last good state.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TypeVar

import numpy as np

from ..emulation.vibration_status import EVENTS, LEVELS, RAMP_CAUSES, STATES, VibrationReport
from ..errors import InvalidInputError, MalformedMessageError
from ..kinematics.rotations import pose_from_position_quaternion
from ..motion.guard_status import GUARD_STATES, TRIP_LIMITS, GuardStatus
from ..vibration.settings import STREAM_KEYS
from .cdr import CdrReader
from .diagnostic_status import DiagnosticStatusData, decode_diagnostic_array, decode_diagnostic_status
from .fields import check_number, check_text, parse_integer, parse_number
from .outcome_codes import NAMES as OUTCOME_NAMES

MAX_VALUES = 512  # key/values of one status (the suite's largest has ~30)
MAX_STATUSES = 1024  # statuses of one DiagnosticArray
LEVEL_NAMES = ("ok", "warn", "error", "stale")  # DiagnosticStatus.OK .. STALE
MAX_PATH = 4096  # characters of a file path in a status (PATH_MAX)
MAX_AMPLITUDE_M = 1.0  # a reported unit amplitude beyond 1 m is no measurement
MAX_LOAD = 1e9  # N or N m: a guard limit or load beyond this is no measurement
QUATERNION_TOLERANCE = 1e-3  # |q| - 1 of a reported pose (kinematics writes unit quaternions)
_REQUIRED = object()
_T = TypeVar("_T")


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
    """A checked StatusMessage of a decoded one (diagnostic_status.DiagnosticStatusData)."""
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


# -- vibration/status (hardware emulator): VibrationUnitsStatus ------------------------------------------------
def _enum(value: int, names: tuple, what: str) -> str:
    if value >= len(names):
        raise MalformedMessageError(f"{what} {value} is not one of 0..{len(names) - 1}", field=what, kind="range")
    return names[value]


def _time(value: float, what: str, nan=_REQUIRED, minus_inf=False):
    """A finite time (s); NaN gives ``nan`` when given, -inf passes when ``minus_inf``."""
    if math.isnan(value) and nan is not _REQUIRED:
        return nan
    if math.isfinite(value) or (minus_inf and value == -math.inf):
        return value
    raise MalformedMessageError(f"{what} {value} is not a finite time", field=what, kind="range")


def _outcome_name(code: int, what: str) -> str:
    if code not in OUTCOME_NAMES:
        raise MalformedMessageError(f"{what} code {code} is not in the outcome table", field=what, kind="range")
    return OUTCOME_NAMES[code]


def _decoded(data, what: str, read: Callable[[CdrReader], _T]) -> _T:
    """``read`` of a CdrReader over ``data`` (``what`` names the type); bytes that are no CDR of it (too short,
    truncated, a bad string) raise MalformedMessageError."""
    try:
        return read(CdrReader(data, what))
    except MalformedMessageError:
        raise
    except InvalidInputError as exc:
        raise MalformedMessageError(str(exc)) from None


def vibration_report_from_cdr(data) -> VibrationReport:
    """The VibrationReport of raw VibrationUnitsStatus bytes (what vibration/status's subscribers read): the
    amplitude (6,) in m, times in s (NaN ramp / event times as None), the enums as their names and the event's
    outcome code as its name. MalformedMessageError for bytes that are no such message, an enum or code out of
    its table, a string that is not clean text, a time that is not finite (commanded_until may be -inf), an
    amplitude outside [0, MAX_AMPLITUDE_M]."""
    return _decoded(data, "VibrationUnitsStatus", _vibration_report)


def _vibration_report(r: CdrReader) -> VibrationReport:
    sec, nanosec = r.stamp()
    check_text(r.string(), "frame_id")
    state, level = _enum(r.u8(), STATES, "state"), _enum(r.u8(), LEVELS, "level")
    reason = check_text(r.string(), "reason")
    since = _time(r.f64(), "since_s")
    amplitude = r.fixed_doubles(6)
    if not (np.isfinite(amplitude).all() and (amplitude >= 0).all() and (amplitude <= MAX_AMPLITUDE_M).all()):
        raise MalformedMessageError(f"amplitude_m {amplitude.tolist()} is not 6 amplitudes in [0, "
                                    f"{MAX_AMPLITUDE_M:g}] m", field="amplitude_m", kind="range")
    commanded_until = _time(r.f64(), "commanded_until_s", minus_inf=True)
    ramp_start = _time(r.f64(), "ramp_start_s", nan=None)
    ramp_cause = _enum(r.u8(), RAMP_CAUSES, "ramp_cause")
    ramp_reason = check_text(r.string(), "ramp_reason")
    event_seq = r.u32()
    event = _enum(r.u8(), EVENTS, "event")
    code, event_reason = r.u16(), check_text(r.string(), "event_outcome.message")
    event_outcome = _outcome_name(code, "event_outcome") if event else ""
    event_stamp = _time(r.f64(), "event_stamp_s", nan=None)
    event_time = _time(r.f64(), "event_time_s", nan=None)
    accepted, refused = r.u32(), r.u32()
    fault = check_text(r.string(), "fault")
    active = r.u8()
    if active > 1:
        raise MalformedMessageError(f"active {active} is not a bool", field="active", kind="range")
    r.end()
    return VibrationReport(
        state=state, level=level, reason=reason, since=since, time=sec + nanosec * 1e-9, amplitude=amplitude,
        commanded_until=commanded_until, ramp_start=ramp_start, ramp_reason=ramp_reason, ramp_cause=ramp_cause,
        event_seq=event_seq, event=event, event_outcome=event_outcome, event_reason=event_reason if event else "",
        event_stamp=event_stamp, event_time=event_time, accepted=accepted, refused=refused, fault=fault,
        active=bool(active))


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


# -- kinematics/guard_status: ForceGuardStatus -------------------------------------------------------------
def _load(value: float, what: str, nan_ok: bool) -> float:
    if (math.isnan(value) and nan_ok) or (math.isfinite(value) and abs(value) <= MAX_LOAD):
        return value
    raise MalformedMessageError(f"{what} {value} is not a load within {MAX_LOAD:g}", field=what, kind="range")


def guard_status_from_cdr(data) -> GuardStatus:
    """The GuardStatus of raw ForceGuardStatus bytes (what kinematics/guard_status's subscribers read).
    MalformedMessageError for bytes that are no such message, a state or limit out of its table, limits that are
    not finite and >= 0, a tripped status without a finite trip time and a limit or with a tripped goal that is
    no pose, a message that is not clean text."""
    return _decoded(data, "ForceGuardStatus", _guard_status)


def _guard_status(r: CdrReader) -> GuardStatus:
    r.stamp()
    check_text(r.string(), "frame_id")
    state = _enum(r.u8(), GUARD_STATES, "state")
    force_limit, moment_limit = r.f64(), r.f64()
    for name, value in (("force_limit_n", force_limit), ("moment_limit_nm", moment_limit)):
        if not (math.isfinite(value) and 0 <= value <= MAX_LOAD):
            raise MalformedMessageError(f"{name} {value} is not a limit >= 0", field=name, kind="range")
    trip_time = r.f64()
    trip_limit = _enum(r.u8(), TRIP_LIMITS, "trip_limit")
    tripped = state == "tripped"
    loads = {name: _load(r.f64(), name, not tripped) for name in (
        "trip_force_n", "trip_moment_nm", "predicted_force_n", "predicted_moment_nm", "peak_force_n",
        "peak_moment_nm", "stop_duration_s", "stop_progress")}
    goal, direction = r.fixed_doubles(7), r.fixed_doubles(6)
    blocked = r.u32()
    message = check_text(r.string(), "message")
    r.end()
    if not tripped:
        return GuardStatus(state, force_limit, moment_limit, message, blocked_directions=blocked)
    if not math.isfinite(trip_time) or not trip_limit:
        raise MalformedMessageError(f"a tripped status needs a finite trip_time_s and a trip_limit (got {trip_time}, "
                                    f"{trip_limit!r})", field="trip_time_s", kind="missing")
    try:
        goal_pose = pose_from_position_quaternion(goal[:3], goal[3:], unit_tolerance=QUATERNION_TOLERANCE)
    except InvalidInputError as exc:
        raise MalformedMessageError(f"tripped_goal: {exc}", field="tripped_goal", kind="range") from None
    if not np.isfinite(direction).all():
        raise MalformedMessageError("tripped_direction is not finite", field="tripped_direction", kind="range")
    return GuardStatus(state, force_limit, moment_limit, message, trip_limit, trip_time, tripped_goal=goal_pose,
                       tripped_direction=direction, blocked_directions=blocked, **loads)


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
