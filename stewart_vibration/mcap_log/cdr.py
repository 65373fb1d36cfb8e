"""Cheap reads from serialized CDR messages (no full decode)."""

from __future__ import annotations

import struct

_LE = struct.Struct("<iI")
_BE = struct.Struct(">iI")


def header_stamp_ns(data: bytes) -> int | None:
    """``header.stamp`` in ns of a CDR message whose first field is std_msgs/Header.

    The 4-byte encapsulation header comes first (byte 1: 0x01 little endian,
    0x00 big endian); the stamp (int32 sec, uint32 nanosec) follows at offset 4.
    Returns None for short data or a zero or negative stamp (unset).
    """
    if len(data) < 12:
        return None
    sec, nsec = (_LE if data[1] & 1 else _BE).unpack_from(data, 4)
    if sec < 0 or (sec == 0 and nsec == 0):
        return None
    return sec * 1_000_000_000 + nsec
