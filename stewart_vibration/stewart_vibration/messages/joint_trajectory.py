"""trajectory_msgs/JointTrajectory as raw CDR (numpy, no rclpy), encoded and decoded through structured numpy
views of the points (uniform points at once, mixed points one by one).

Stamp in s (0 = now), times_from_start in s from the stamp, positions / velocities / accelerations [n, k] in the
joints' units (m, m/s, m/s^2 for the struts) in the message's name order; header.frame_id is passed through.
"""

# The dtype builders append to three lists as one tuple statement per field (the tuple of Nones is discarded):
# mypy: disable-error-code="func-returns-value"

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError
from .cdr import NANOSEC_PER_SEC, CdrReader, CdrWriter, stamp_parts, stamp_seconds


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
    w = CdrWriter()
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
