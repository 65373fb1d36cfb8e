"""The CDR wire format of ROS 2 messages (little endian) with numpy, no rclpy: the sequential reader and writer
the message codecs build on, and time stamps (s <-> sec, nanosec; a header's stamp; rosgraph_msgs/Clock).

The nodes publish and subscribe the suite's high-rate topics raw (bytes), which skips rclpy's per-field Python
object construction: encoding a JointState costs a few microseconds instead of ~25. The codecs, one module per
message family: ``joint_states`` (sensor_msgs/JointState), ``stamped_doubles`` (geometry_msgs/PoseStamped,
WrenchStamped, sensor_msgs/Imu), ``joint_trajectory`` (trajectory_msgs/JointTrajectory) and, decoded only,
``diagnostic_status`` (diagnostic_msgs/DiagnosticStatus and DiagnosticArray, read raw so a string's bytes after a
NUL, which rclpy's conversion drops, are seen). Layout (XCDR1): a 4-byte encapsulation header (00 01 00 00), then
the fields, each aligned to its size relative to the end of that header; strings are a uint32 length (with the
NUL), the bytes and a NUL; sequences a uint32 count and the elements. Decoders check every length against the
buffer, that strings are UTF-8 and NUL-terminated (a NUL inside is kept, for the readers to refuse) and that a
stamp's nanosec is below 1e9, and raise InvalidInputError on malformed data.
"""

from __future__ import annotations

import struct

import numpy as np

from ..errors import InvalidInputError

ENCAPSULATION = b"\x00\x01\x00\x00"  # CDR little endian
U32 = struct.Struct("<I")
_U16 = struct.Struct("<H")
_F64 = struct.Struct("<d")
STAMP = struct.Struct("<iI")
_STAMP_BE = struct.Struct(">iI")  # header stamps of big-endian CDR (header_stamp_ns reads any encoding)
F8 = np.dtype("<f8")
STAMP_DTYPE = np.dtype([("sec", "<i4"), ("nanosec", "<u4")])
NANOSEC_PER_SEC = 1_000_000_000


def align(offset: int, size: int) -> int:
    """Offset rounded up to ``size`` relative to the payload start (4 bytes in)."""
    rel = offset - 4
    return offset + (-rel) % size


class CdrWriter:
    """Sequential CDR writer (used to build templates, not on the hot path)."""

    def __init__(self):
        self.buf = bytearray(ENCAPSULATION)

    def pad(self, size: int) -> None:
        """Zero-pad to the next multiple of ``size`` (CDR alignment)."""
        self.buf += b"\x00" * (align(len(self.buf), size) - len(self.buf))

    def u32(self, value: int) -> None:
        """A uint32."""
        self.pad(4)
        self.buf += U32.pack(value)

    def stamp(self, sec: int, nanosec: int) -> None:
        """A builtin_interfaces/Time (sec, nanosec)."""
        self.pad(4)
        self.buf += STAMP.pack(sec, nanosec)

    def string(self, text: str) -> None:
        """A UTF-8 string with its NUL."""
        data = text.encode() + b"\x00"
        self.u32(len(data))
        self.buf += data

    def doubles(self, values) -> int:
        """Write a sequence<float64>; returns the offset of its first element."""
        values = np.asarray(values, dtype=F8).ravel()
        self.u32(values.size)
        if values.size:
            self.pad(8)
        offset = len(self.buf)
        self.buf += values.tobytes()
        return offset

    def fixed_doubles(self, values) -> int:
        """Write float64 fields of a struct (no count); returns the offset of the first."""
        self.pad(8)
        offset = len(self.buf)
        self.buf += np.asarray(values, dtype=F8).tobytes()
        return offset


class CdrReader:
    """Sequential CDR reader with bounds checks."""

    def __init__(self, data, what: str):
        self.data = memoryview(data)
        self.pos = 4
        self.what = what
        if len(self.data) < 4 or bytes(self.data[:2]) != b"\x00\x01":
            raise InvalidInputError(f"{what}: not little-endian CDR data ({len(self.data)} bytes)")

    def need(self, size: int) -> None:
        """Raise unless ``size`` more bytes are left."""
        if self.pos + size > len(self.data) or size < 0:
            raise InvalidInputError(f"{self.what}: truncated at byte {self.pos} (needs {size} more of "
                                    f"{len(self.data)})")

    def pad(self, size: int) -> None:
        """Skip to the next multiple of ``size`` (CDR alignment)."""
        self.pos = align(self.pos, size)

    def u32(self) -> int:
        """A uint32."""
        self.pad(4)
        self.need(4)
        value = U32.unpack_from(self.data, self.pos)[0]
        self.pos += 4
        return value

    def u8(self) -> int:
        """A uint8."""
        self.need(1)
        value = self.data[self.pos]
        self.pos += 1
        return value

    def u16(self) -> int:
        """A uint16."""
        self.pad(2)
        self.need(2)
        value = _U16.unpack_from(self.data, self.pos)[0]
        self.pos += 2
        return value

    def f64(self) -> float:
        """A float64."""
        self.pad(8)
        self.need(8)
        value = _F64.unpack_from(self.data, self.pos)[0]
        self.pos += 8
        return value

    def end(self) -> None:
        """Raise unless every byte was read (up to the 3 bytes of padding CDR may end with)."""
        if len(self.data) - self.pos > 3:
            raise InvalidInputError(f"{self.what}: {len(self.data) - self.pos} bytes after the message")

    def stamp(self) -> tuple[int, int]:
        """A builtin_interfaces/Time as (sec, nanosec); nanosec below 1e9."""
        self.pad(4)
        self.need(8)
        value = STAMP.unpack_from(self.data, self.pos)
        if value[1] >= NANOSEC_PER_SEC:
            raise InvalidInputError(f"{self.what}: a time's nanosec {value[1]} is not below 1e9 (byte {self.pos})")
        self.pos += 8
        return value

    def string(self) -> str:
        """A NUL-terminated UTF-8 string (any NUL inside kept)."""
        n = self.u32()
        self.need(n)
        raw = bytes(self.data[self.pos:self.pos + n])
        self.pos += n
        if n == 0 or raw[-1] != 0:
            raise InvalidInputError(f"{self.what}: malformed string at byte {self.pos - n}")
        try:
            return raw[:-1].decode()
        except UnicodeDecodeError as exc:
            raise InvalidInputError(f"{self.what}: string is not UTF-8 ({exc})") from None

    def strings(self) -> list[str]:
        """A sequence of strings."""
        count = self.u32()
        if count > len(self.data):
            raise InvalidInputError(f"{self.what}: sequence of {count} strings cannot fit")
        return [self.string() for _ in range(count)]

    def doubles(self) -> np.ndarray:
        """A sequence of float64 (a copy)."""
        n = self.u32()
        if n:
            self.pad(8)
        self.need(8 * n)
        values = np.frombuffer(self.data, dtype=F8, count=n, offset=self.pos).copy()
        self.pos += 8 * n
        return values

    def fixed_doubles(self, n: int) -> np.ndarray:
        """An array of ``n`` float64 (a copy)."""
        self.pad(8)
        self.need(8 * n)
        values = np.frombuffer(self.data, dtype=F8, count=n, offset=self.pos).copy()
        self.pos += 8 * n
        return values


def header_stamp_ns(data: bytes) -> int | None:
    """``header.stamp`` in ns of a CDR message whose first field is std_msgs/Header.

    The 4-byte encapsulation header comes first (byte 1: 0x01 little endian,
    0x00 big endian); the stamp (int32 sec, uint32 nanosec) follows at offset 4.
    Returns None for short data or a zero or negative stamp (unset).
    """
    if len(data) < 12:
        return None
    sec, nsec = (STAMP if data[1] & 1 else _STAMP_BE).unpack_from(data, 4)
    if sec < 0 or (sec == 0 and nsec == 0):
        return None
    return sec * 1_000_000_000 + nsec


def stamp_parts(seconds: float) -> tuple[int, int]:
    """(sec, nanosec) of a time in seconds, rounded to the nanosecond (4.9999999999 -> (5, 0))."""
    sec, nanosec = divmod(int(round(seconds * 1e9)), 1_000_000_000)
    return sec, nanosec


def stamp_seconds(sec: int, nanosec: int) -> float:
    """Seconds of a (sec, nanosec) time stamp."""
    return sec + nanosec * 1e-9


def encode_clock(stamp_s: float) -> bytes:
    """rosgraph_msgs/Clock bytes."""
    return ENCAPSULATION + STAMP.pack(*stamp_parts(stamp_s))
