"""Serialized ROS 2 messages (CDR, little endian) of the suite's high-rate topics, with numpy (no rclpy).

The nodes publish and subscribe these topics raw (bytes), which skips rclpy's per-field Python
object construction: encoding a JointState here costs a few microseconds instead of ~25.
Covered types: sensor_msgs/JointState, geometry_msgs/PoseStamped, geometry_msgs/WrenchStamped,
rosgraph_msgs/Clock, trajectory_msgs/JointTrajectory; decoded only: diagnostic_msgs/DiagnosticStatus
and DiagnosticArray (read raw so a string's bytes after a NUL, which rclpy's conversion drops, are
seen). Layout (XCDR1): a 4-byte encapsulation header (00 01 00 00), then the fields, each aligned to
its size relative to the end of that header; strings are a uint32 length (with the NUL), the bytes
and a NUL; sequences a uint32 count and the elements. Decoders check every length against the
buffer, that strings are UTF-8 and NUL-terminated (a NUL inside is kept, for the readers to refuse)
and that a stamp's nanosec is below 1e9, and raise InvalidInputError on malformed data.
"""

# The dtype builders append to three lists as one tuple statement per field (the tuple of Nones is discarded):
# mypy: disable-error-code="func-returns-value"

from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError

ENCAPSULATION = b"\x00\x01\x00\x00"  # CDR little endian
_U32 = struct.Struct("<I")
_U16 = struct.Struct("<H")
_F64 = struct.Struct("<d")
_STAMP = struct.Struct("<iI")
_STAMP_BE = struct.Struct(">iI")  # header stamps of big-endian CDR (header_stamp_ns reads any encoding)
_F8 = np.dtype("<f8")
_STAMP_DTYPE = np.dtype([("sec", "<i4"), ("nanosec", "<u4")])
NANOSEC_PER_SEC = 1_000_000_000


def _align(offset: int, size: int) -> int:
    """Offset rounded up to ``size`` relative to the payload start (4 bytes in)."""
    rel = offset - 4
    return offset + (-rel) % size


class _Writer:
    """Sequential CDR writer (used to build templates, not on the hot path)."""

    def __init__(self):
        self.buf = bytearray(ENCAPSULATION)

    def pad(self, size: int) -> None:
        """Zero-pad to the next multiple of ``size`` (CDR alignment)."""
        self.buf += b"\x00" * (_align(len(self.buf), size) - len(self.buf))

    def u32(self, value: int) -> None:
        self.pad(4)
        self.buf += _U32.pack(value)

    def stamp(self, sec: int, nanosec: int) -> None:
        self.pad(4)
        self.buf += _STAMP.pack(sec, nanosec)

    def string(self, text: str) -> None:
        data = text.encode() + b"\x00"
        self.u32(len(data))
        self.buf += data

    def doubles(self, values) -> int:
        """Write a sequence<float64>; returns the offset of its first element."""
        values = np.asarray(values, dtype=_F8).ravel()
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
        self.buf += np.asarray(values, dtype=_F8).tobytes()
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
        self.pos = _align(self.pos, size)

    def u32(self) -> int:
        """A uint32."""
        self.pad(4)
        self.need(4)
        value = _U32.unpack_from(self.data, self.pos)[0]
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
        value = _STAMP.unpack_from(self.data, self.pos)
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
        values = np.frombuffer(self.data, dtype=_F8, count=n, offset=self.pos).copy()
        self.pos += 8 * n
        return values

    def fixed_doubles(self, n: int) -> np.ndarray:
        """An array of ``n`` float64 (a copy)."""
        self.pad(8)
        self.need(8 * n)
        values = np.frombuffer(self.data, dtype=_F8, count=n, offset=self.pos).copy()
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
    sec, nsec = (_STAMP if data[1] & 1 else _STAMP_BE).unpack_from(data, 4)
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


# -- sensor_msgs/JointState --------------------------------------------------------------------
@dataclass(frozen=True)
class JointStateData:
    """A decoded JointState: stamp (s), frame_id, names, position / velocity / effort [k] (may be empty)."""

    stamp: float
    frame_id: str
    names: tuple
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray


class JointStateEncoder:
    """Encodes JointStates of fixed names and frame: bytes template + three array offsets."""

    def __init__(self, names, frame_id: str = "", fields=("position", "velocity", "effort")):
        self.names = list(names)
        self.fields = tuple(fields)
        w = _Writer()
        w.stamp(0, 0)
        w.string(frame_id)
        w.u32(len(self.names))
        for name in self.names:
            w.string(name)
        self.offsets = {}
        for field in ("position", "velocity", "effort"):
            self.offsets[field] = w.doubles(np.zeros(len(self.names) if field in self.fields else 0))
        self.template = bytes(w.buf)

    def encode(self, stamp_s: float, position=None, velocity=None, effort=None) -> bytes:
        """JointState bytes at ``stamp_s`` (s); position / velocity / effort [k] in ``names`` order (m, m/s, N
        for the legs). A field not in ``fields`` is sent empty and its argument ignored."""
        buf = bytearray(self.template)
        _STAMP.pack_into(buf, 4, *stamp_parts(stamp_s))
        n = len(self.names)
        for field, values in (("position", position), ("velocity", velocity), ("effort", effort)):
            if field in self.fields:
                np.frombuffer(buf, dtype=_F8, count=n, offset=self.offsets[field])[:] = values
        return bytes(buf)


class JointStateDecoder:
    """Decodes JointState bytes; caches the name block so repeated layouts skip the string parsing."""

    def __init__(self):
        self._names_key = None
        self._names = ()

    def decode(self, data) -> JointStateData:
        """Decode one JointState's bytes; raises InvalidInputError on malformed data."""
        r = CdrReader(data, "JointState")
        sec, nanosec = r.stamp()
        frame = r.string()
        start = r.pos
        key = self._names_key
        if key is not None and bytes(r.data[start:start + len(key)]) == key:
            names, r.pos = self._names, start + len(key)
        else:
            names = tuple(r.strings())
            self._names_key, self._names = bytes(r.data[start:r.pos]), names
        return JointStateData(stamp_seconds(sec, nanosec), frame, names, r.doubles(), r.doubles(), r.doubles())


@dataclass(frozen=True)
class JointStateBatch:
    """Many JointStates with the same names: stamps [n] (s), names, position / velocity / effort [n, k]
    (NaN where a message left a field empty)."""

    stamps: np.ndarray
    names: tuple
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray


def decode_joint_states(messages, decoder: JointStateDecoder | None = None) -> list[JointStateBatch]:
    """Decode raw JointStates; consecutive messages with one layout (same size and name block, as a
    publisher's stream has) are decoded together with one numpy view. Returns one batch per run of
    equal names, in order. Raises InvalidInputError on the first malformed message (the caller may
    decode the rest one by one to drop only that one)."""
    decoder = decoder or JointStateDecoder()
    batches: list[JointStateBatch] = []
    i, n = 0, len(messages)
    while i < n:
        first = decoder.decode(messages[i])
        size, key = len(messages[i]), decoder._names_key
        j = i + 1
        while j < n and len(messages[j]) == size and _same_layout(messages[j], messages[i], key):
            j += 1
        k = len(first.names)
        counts = (first.position.size, first.velocity.size, first.effort.size)
        stacked = _stack_uniform(messages[i:j], first, counts) if j - i > 1 and all(c in (0, k) for c in counts) \
            else None
        if stacked is not None:
            stamps, arrays = stacked
        else:
            decoded = [first] + [decoder.decode(m) for m in messages[i + 1:j]]
            stamps = np.array([d.stamp for d in decoded])
            arrays = [np.array([_padded(getattr(d, f), k) for d in decoded])
                      for f in ("position", "velocity", "effort")]
        batches.append(JointStateBatch(stamps, first.names, *arrays))
        i = j
    return batches



def decode_joint_states_dropping_malformed(messages, decoder: JointStateDecoder | None = None,
                                           on_malformed: Callable[[str], None] | None = None
                                           ) -> tuple[list[JointStateBatch], np.ndarray]:
    """decode_joint_states that drops only the malformed messages, each reported to ``on_malformed(reason)``.

    Returns the batches and the indices (into ``messages``) of the messages they hold, in order, so a
    caller can pick the matching arrival times: ``arrivals[kept]`` lines up row for row with the batches.
    """
    decoder = decoder or JointStateDecoder()
    try:
        return decode_joint_states(messages, decoder), np.arange(len(messages))
    except InvalidInputError:
        pass
    kept = []
    for i, data in enumerate(messages):  # find the malformed ones, then decode the rest together again
        try:
            decoder.decode(data)
            kept.append(i)
        except InvalidInputError as exc:
            if on_malformed is not None:
                on_malformed(str(exc))
    return decode_joint_states([messages[i] for i in kept], decoder), np.array(kept, dtype=int)

def _padded(values: np.ndarray, k: int) -> np.ndarray:
    return values if values.size == k else np.full(k, np.nan)


def _same_layout(data, reference, names_key: bytes) -> bool:
    """Same frame and name block as ``reference`` (bytes 12.. up to the end of the names)."""
    start = 12 + _U32.unpack_from(reference, 12)[0] + 4  # after the frame_id string
    start = _align(start, 4)
    return bytes(data[12:start + len(names_key)]) == bytes(reference[12:start + len(names_key)])


def _stack_uniform(messages, first: JointStateData, counts):
    """Stamps and the three arrays of equal-layout messages through one structured view (None if
    their array counts differ)."""
    k = len(first.names)
    size = len(messages[0])
    # offsets of the arrays in the first message (the same in all)
    r = CdrReader(messages[0], "JointState")
    r.stamp()
    r.string()
    r.strings()
    offsets, count_at = [], []
    for _ in counts:
        r.pad(4)
        count_at.append(r.pos)
        n = r.u32()
        if n:
            r.pad(8)
        offsets.append(r.pos)
        r.pos += 8 * n
    formats: list[str | tuple[str, tuple[int]]]
    names, formats, offs = ["sec", "nanosec"], ["<i4", "<u4"], [4, 8]
    for field, count, offset, at in zip(("position", "velocity", "effort"), counts, offsets, count_at, strict=True):
        names.append(f"n_{field}"), formats.append("<u4"), offs.append(at)
        if count:
            names.append(field), formats.append(("<f8", (count,))), offs.append(offset)
    dtype = np.dtype({"names": names, "formats": formats, "offsets": offs, "itemsize": size})
    table = np.frombuffer(b"".join(bytes(m) for m in messages), dtype=dtype)
    if any((table[f"n_{f}"] != c).any() for f, c in zip(("position", "velocity", "effort"), counts, strict=True)):
        return None  # same size and names but the arrays are split differently: decode one by one
    if (table["nanosec"] >= NANOSEC_PER_SEC).any():
        raise InvalidInputError("JointState: a stamp's nanosec is not below 1e9")
    stamps = table["sec"] + table["nanosec"] * 1e-9
    arrays = [table[f].copy() if c else np.full((len(messages), k), np.nan)
              for f, c in zip(("position", "velocity", "effort"), counts, strict=True)]
    return stamps, arrays


# -- geometry_msgs/PoseStamped, WrenchStamped; sensor_msgs/Imu; rosgraph_msgs/Clock -------------------
class _HeaderDoublesEncoder:
    """A message laid out as Header (fixed frame) + float64 fields: a template, and per message its stamp and
    a writable view of the doubles."""

    def __init__(self, frame_id: str, fields):
        w = _Writer()
        w.stamp(0, 0)
        w.string(frame_id)
        self.count = len(fields)
        self.offset = w.fixed_doubles(fields)
        self.template = bytes(w.buf)

    def _stamped(self, stamp_s: float) -> tuple[bytearray, np.ndarray]:
        """(a copy of the template stamped ``stamp_s`` (s), the view of its doubles)."""
        buf = bytearray(self.template)
        _STAMP.pack_into(buf, 4, *stamp_parts(stamp_s))
        return buf, np.frombuffer(buf, dtype=_F8, count=self.count, offset=self.offset)


class PoseStampedEncoder(_HeaderDoublesEncoder):
    """PoseStamped in a fixed frame: position (3,) m and quaternion (4,) [x, y, z, w]."""

    def __init__(self, frame_id: str):
        super().__init__(frame_id, np.zeros(7))

    def encode(self, stamp_s: float, position, quaternion) -> bytes:
        """PoseStamped bytes at ``stamp_s`` (s): position (3,) m and quaternion (4,) [x, y, z, w], encoder's frame."""
        buf, values = self._stamped(stamp_s)
        values[:3], values[3:] = position, quaternion
        return bytes(buf)


def _decode_header_doubles(data, type_name: str, count: int) -> tuple[float, str, np.ndarray]:
    """(stamp s, frame_id, the ``count`` doubles after the header) of a message made of a Header and doubles."""
    r = CdrReader(data, type_name)
    sec, nanosec = r.stamp()
    frame = r.string()
    return stamp_seconds(sec, nanosec), frame, r.fixed_doubles(count)


def decode_pose_stamped(data) -> tuple[float, str, np.ndarray, np.ndarray]:
    """(stamp s, frame_id, position (3,), quaternion (4,) [x, y, z, w]) of PoseStamped bytes."""
    stamp, frame, values = _decode_header_doubles(data, "PoseStamped", 7)
    return stamp, frame, values[:3], values[3:]


class WrenchStampedEncoder(_HeaderDoublesEncoder):
    """WrenchStamped in a fixed frame: force (3,) N and torque (3,) N m."""

    def __init__(self, frame_id: str):
        super().__init__(frame_id, np.zeros(6))

    def encode(self, stamp_s: float, wrench) -> bytes:
        """WrenchStamped bytes at ``stamp_s`` (s): wrench (6,) [force (N), torque (N m)] in the encoder's frame."""
        buf, values = self._stamped(stamp_s)
        values[:] = wrench
        return bytes(buf)


class ImuEncoder(_HeaderDoublesEncoder):
    """sensor_msgs/Imu in a fixed frame, without an orientation estimate (orientation_covariance[0] = -1, the
    message's convention): angular velocity (3,) rad/s and linear acceleration (3,) m/s^2 with diagonal
    covariances."""

    def __init__(self, frame_id: str):
        fields = np.zeros(37)  # orientation 4, its covariance 9, angular velocity 3 + 9, linear acceleration 3 + 9
        fields[3], fields[4] = 1.0, -1.0
        super().__init__(frame_id, fields)

    def encode(self, stamp_s: float, angular_velocity, linear_acceleration, gyro_variance: float = 0.0,
               accel_variance: float = 0.0) -> bytes:
        """Imu bytes at ``stamp_s`` (s): rates (3,) rad/s and specific force (3,) m/s^2, the encoder's frame."""
        buf, values = self._stamped(stamp_s)
        values[13:16], values[25:28] = angular_velocity, linear_acceleration
        values[[16, 20, 24]], values[[28, 32, 36]] = gyro_variance, accel_variance
        return bytes(buf)


def decode_imu(data) -> tuple[float, str, np.ndarray, np.ndarray]:
    """(stamp s, frame_id, angular velocity (3,) rad/s, linear acceleration (3,) m/s^2) of Imu bytes."""
    stamp, frame, values = _decode_header_doubles(data, "Imu", 37)
    return stamp, frame, values[13:16], values[25:28]


def decode_wrench_stamped(data) -> tuple[float, str, np.ndarray]:
    """(stamp s, frame_id, wrench (6,) [force N, torque N m]) of WrenchStamped bytes."""
    return _decode_header_doubles(data, "WrenchStamped", 6)


def decode_stamped_doubles(messages, count: int, what: str) -> tuple[np.ndarray, list, np.ndarray, np.ndarray, list]:
    """Decode many raw messages laid out as Header + ``count`` float64 (PoseStamped: 7, WrenchStamped: 6).

    Messages of one size whose bytes up to the doubles equal the first's but for the stamp (a publisher's stream:
    same frame) are decoded together through numpy views of the joined bytes; the others one by one.

    Args:
        messages: the raw messages (bytes).
        count: the float64 fields after the header.
        what: the type's name for error messages.

    Returns:
        (stamps [m] (s), frame_ids [m] (str), values [m, count], kept [m] (indices of the decoded messages, in
        order), errors (InvalidInputError of each message that could not be decoded)).
    """
    by_size: dict[int, list[int]] = {}
    for i, data in enumerate(messages):
        by_size.setdefault(len(data), []).append(i)
    stamps, frames, values, kept, errors = [], [], [], [], []
    for size, group in by_size.items():
        start = None
        try:
            r = CdrReader(messages[group[0]], what)
            r.stamp()
            frame = r.string()
            r.pad(8)
            r.need(8 * count)
            start = r.pos
        except InvalidInputError:
            pass  # decoded one by one below, which reports it
        if start is not None and len(group) > 1:
            n = len(group)
            joined = b"".join([messages[i] for i in group])
            header = np.ndarray((n, start), np.uint8, joined, 0, (size, 1))
            differs = header != header[0]
            differs[:, 4:12] = False  # the stamp may differ
            times = np.ndarray((n,), _STAMP_DTYPE, joined, 4, (size,))
            uniform = ~differs.any(axis=1) & (times["nanosec"] < NANOSEC_PER_SEC)
            table = np.ndarray((n, count), _F8, joined, start, (size, 8))
            if uniform.all():
                stamps.append(times["sec"] + times["nanosec"] * 1e-9)
                values.append(table.copy())
                frames.extend([frame] * n)
                kept.append(np.asarray(group))
                continue
            stamps.append(times["sec"][uniform] + times["nanosec"][uniform] * 1e-9)
            values.append(table[uniform])
            frames.extend([frame] * int(uniform.sum()))
            kept.append(np.asarray(group)[uniform])
            group = [group[j] for j in np.flatnonzero(~uniform)]
        for i in group:  # the rest one by one
            try:
                r = CdrReader(messages[i], what)
                sec, nanosec = r.stamp()
                frame_i = r.string()
                row = r.fixed_doubles(count)
            except InvalidInputError as exc:
                errors.append(exc)
                continue
            frames.append(frame_i)
            stamps.append(np.array([stamp_seconds(sec, nanosec)]))
            values.append(row[None, :])
            kept.append(np.array([i]))
    if not kept:
        return np.empty(0), [], np.empty((0, count)), np.empty(0, int), errors
    if len(kept) == 1:
        return stamps[0], frames, values[0], kept[0], errors
    indices = np.concatenate(kept)
    order = np.argsort(indices, kind="stable")
    if (order != np.arange(len(order))).any():  # one-by-one rows among the others: back in arrival order
        frames = [frames[j] for j in order]
    return np.concatenate(stamps)[order], frames, np.concatenate(values)[order], indices[order], errors


def encode_clock(stamp_s: float) -> bytes:
    """rosgraph_msgs/Clock bytes."""
    return ENCAPSULATION + _STAMP.pack(*stamp_parts(stamp_s))


# -- trajectory_msgs/JointTrajectory -----------------------------------------------------------------
@dataclass(frozen=True)
class TrajectoryData:
    """A decoded JointTrajectory: stamp (s, 0 = now), frame_id, names, times [n] (s from the stamp),
    positions / velocities / accelerations [n, k] (None when every point leaves them empty)."""

    stamp: float
    frame_id: str
    names: tuple
    times: np.ndarray
    positions: np.ndarray | None
    velocities: np.ndarray | None
    accelerations: np.ndarray | None


_POINT_FIELDS = ("positions", "velocities", "accelerations", "effort")


def _point_dtype(phase: int, counts: tuple) -> tuple[np.dtype, int]:
    """numpy dtype of one JointTrajectoryPoint starting at ``phase`` (payload offset mod 8: 0 or 4)
    with the given per-field counts; returns (dtype, size in bytes)."""
    formats: list[str | tuple[str, tuple[int]]]
    names, formats, offsets = [], [], []
    o = phase
    for field, n in zip(_POINT_FIELDS, counts, strict=True):
        o += (-o) % 4
        names.append(f"n_{field}"), formats.append("<u4"), offsets.append(o - phase)
        o += 4
        if n:
            o += (-o) % 8
            names.append(field), formats.append(("<f8", (n,))), offsets.append(o - phase)
            o += 8 * n
    o += (-o) % 4
    names += ["sec", "nanosec"]
    formats += ["<i4", "<u4"]
    offsets += [o - phase, o - phase + 4]
    o += 8
    return np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": o - phase}), o - phase


def _points_view(buf, offset: int, count: int, counts: tuple):
    """[(structured array, point indices)] over ``count`` uniform points starting at byte ``offset``,
    and the bytes they use. A point's layout depends on its start offset mod 8 (0 or 4): the
    sequence of layouts is constant, alternates, or changes once after the first point."""
    views, index, used = [], 0, 0

    def layout(pos):
        return _point_dtype((pos - 4) % 8, counts)

    pos = offset
    dtype0, size0 = layout(pos)
    dtype1, size1 = layout(pos + size0)
    if count and size0 % 8 and (size0 + size1) % 8:  # the layout changes once: peel the first point
        views.append((np.frombuffer(buf, dtype=dtype0, count=1, offset=pos), slice(0, 1)))
        pos, index, used = pos + size0, 1, size0
        dtype0, size0 = layout(pos)
        dtype1, size1 = layout(pos + size0)
    rest = count - index
    if size0 % 8 == 0:  # constant layout
        views.append((np.frombuffer(buf, dtype=dtype0, count=rest, offset=pos), slice(index, count)))
        return views, used + size0 * rest
    pair = np.dtype({"names": ["a", "b"], "formats": [dtype0, dtype1], "offsets": [0, size0],
                     "itemsize": size0 + size1})
    pairs = rest // 2
    both = np.frombuffer(buf, dtype=pair, count=pairs, offset=pos)
    views += [(both["a"], slice(index, index + 2 * pairs, 2)), (both["b"], slice(index + 1, index + 2 * pairs, 2))]
    used += pairs * (size0 + size1)
    if rest % 2:
        views.append((np.frombuffer(buf, dtype=dtype0, count=1, offset=pos + pairs * (size0 + size1)),
                      slice(count - 1, count)))
        used += size0
    return views, used


def encode_joint_trajectory(names, stamp_s: float, times, positions, velocities=None, accelerations=None,
                            frame_id: str = "") -> bytes:
    """JointTrajectory bytes: names [k], stamp (s; 0 = now), times [n] (s from the stamp),
    positions / velocities / accelerations [n, k] (velocities and accelerations optional)."""
    times = np.asarray(times, dtype=float)
    n, k = times.size, len(names)
    w = _Writer()
    w.stamp(*stamp_parts(stamp_s) if stamp_s > 0 else (0, 0))
    w.string(frame_id)
    w.u32(k)
    for name in names:
        w.string(name)
    w.u32(n)
    data = {"positions": positions, "velocities": velocities, "accelerations": accelerations}
    counts = tuple(k if data.get(f) is not None else 0 for f in _POINT_FIELDS)
    offset = len(w.buf)
    _, size = _point_dtype((offset - 4) % 8, counts)
    buf = w.buf + bytearray((size + 4) * n)  # alternating layouts differ by at most 4 bytes of padding
    views, used = _points_view(buf, offset, n, counts)
    sec_ns = np.round(times * 1e9).astype(np.int64)
    for view, index in views:
        for field, count in zip(_POINT_FIELDS, counts, strict=True):
            view[f"n_{field}"] = count
            if count:
                view[field] = np.asarray(data[field], dtype=float)[index]
        view["sec"], view["nanosec"] = np.divmod(sec_ns[index], 1_000_000_000)
    return bytes(buf[:offset + used])


def decode_joint_trajectory(data) -> TrajectoryData:
    """Decode JointTrajectory bytes (uniform points vectorised, mixed points one by one)."""
    r = CdrReader(data, "JointTrajectory")
    sec, nanosec = r.stamp()
    frame = r.string()
    names = tuple(r.strings())
    count = r.u32()
    if count > len(r.data):
        raise InvalidInputError(f"JointTrajectory: {count} points cannot fit in {len(r.data)} bytes")
    fields: dict[str, list[np.ndarray]] = {f: [] for f in _POINT_FIELDS}
    times = np.empty(count)
    if count:
        start = r.pos
        counts: list[int] | tuple[int, ...]  # a list while read, then a tuple
        counts = []
        probe = r.pos
        for _ in _POINT_FIELDS:  # counts of the first point
            n = r.u32()
            counts.append(n)
            if n:
                r.pad(8)
                r.need(8 * n)
                r.pos += 8 * n
        counts = tuple(counts)
        r.pos = probe
        uniform = None
        try:
            views, used = _points_view(r.data, start, count, counts)
            if start + used <= len(r.data) and all(
                    (v[f"n_{f}"] == c).all() for v, _ in views for f, c in zip(_POINT_FIELDS, counts, strict=True)):
                uniform = views, used
        except ValueError:  # buffer too short for the uniform layout
            uniform = None
        if uniform is not None:
            views, used = uniform
            table = {f: np.empty((count, c)) for f, c in zip(_POINT_FIELDS, counts, strict=True)}
            for view, index in views:
                if (view["nanosec"] >= NANOSEC_PER_SEC).any():
                    raise InvalidInputError("JointTrajectory: a time_from_start's nanosec is not below 1e9")
                for field, c in zip(_POINT_FIELDS, counts, strict=True):
                    if c:
                        table[field][index] = view[field]
                times[index] = view["sec"] + view["nanosec"] * 1e-9
            r.pos = start + used
            out = {f: (table[f] if c else None) for f, c in zip(_POINT_FIELDS, counts, strict=True)}
        else:
            for i in range(count):
                for field in _POINT_FIELDS:
                    fields[field].append(r.doubles())
                s, ns = r.stamp()
                times[i] = s + ns * 1e-9
            out = {}
            for field in _POINT_FIELDS:
                rows = fields[field]
                if all(len(row) == 0 for row in rows):
                    out[field] = None
                elif len({len(row) for row in rows}) != 1:
                    raise InvalidInputError(f"JointTrajectory: points differ in their number of {field}")
                else:
                    out[field] = np.array(rows)
    else:
        out = dict.fromkeys(_POINT_FIELDS)
    return TrajectoryData(stamp_seconds(sec, nanosec), frame, names, times, out["positions"], out["velocities"],
                          out["accelerations"])


# -- diagnostic_msgs/DiagnosticStatus, DiagnosticArray (decode only) --------------------------------------
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
