"""diagnostic_msgs/DiagnosticStatus and DiagnosticArray decoded from raw CDR (no rclpy): read raw so a string's
bytes after a NUL, which rclpy's conversion drops, are seen (``status_values`` refuses them). Stamp in s.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import InvalidInputError
from .cdr import CdrReader, stamp_seconds


@dataclass(frozen=True)
class DiagnosticStatusData:
    """A decoded DiagnosticStatus as it is on the wire (strings with any NUL kept, not yet checked):
    level (the byte, 0..255), name, message, hardware_id, values ((key, value) pairs in order)."""

    level: int
    name: str
    message: str
    hardware_id: str
    values: tuple


def _diagnostic_status(r: CdrReader) -> DiagnosticStatusData:
    level = r.u8()
    name, message, hardware_id = r.string(), r.string(), r.string()
    count = r.u32()
    if count > len(r.data):
        raise InvalidInputError(f"{r.what}: sequence of {count} key/values cannot fit")
    values = tuple((r.string(), r.string()) for _ in range(count))
    return DiagnosticStatusData(level, name, message, hardware_id, values)


def decode_diagnostic_status(data) -> DiagnosticStatusData:
    """Decode DiagnosticStatus bytes (InvalidInputError on malformed data)."""
    return _diagnostic_status(CdrReader(data, "DiagnosticStatus"))


def decode_diagnostic_array(data) -> tuple[float, str, list[DiagnosticStatusData]]:
    """(stamp s, frame_id, statuses) of DiagnosticArray bytes (InvalidInputError on malformed data)."""
    r = CdrReader(data, "DiagnosticArray")
    sec, nanosec = r.stamp()
    frame = r.string()
    count = r.u32()
    if count > len(r.data):
        raise InvalidInputError(f"DiagnosticArray: sequence of {count} statuses cannot fit")
    return stamp_seconds(sec, nanosec), frame, [_diagnostic_status(r) for _ in range(count)]
