"""sensor_msgs/JointState as raw CDR (numpy, no rclpy): an encoder of fixed names and frame, a decoder that caches
the name block, and the decoding of a stream at once (messages of one layout through one numpy view).

Stamps in s; position / velocity / effort in the joints' units (m, m/s, N for the legs), in the message's name
order; header.frame_id is passed through as it is.
"""

# The dtype builders append to three lists as one tuple statement per field (the tuple of Nones is discarded):
# mypy: disable-error-code="func-returns-value"

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError
from .cdr import F8, NANOSEC_PER_SEC, STAMP, U32, CdrReader, CdrWriter, align, stamp_parts, stamp_seconds


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
        w = CdrWriter()
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
        STAMP.pack_into(buf, 4, *stamp_parts(stamp_s))
        n = len(self.names)
        for field, values in (("position", position), ("velocity", velocity), ("effort", effort)):
            if field in self.fields:
                np.frombuffer(buf, dtype=F8, count=n, offset=self.offsets[field])[:] = values
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
    start = 12 + U32.unpack_from(reference, 12)[0] + 4  # after the frame_id string
    start = align(start, 4)
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
