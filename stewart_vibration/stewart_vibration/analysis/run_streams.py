"""A run's recorded topics decoded into arrays in one pass over its MCAP (pure: no rclpy, no mcap_ros2).

The high-rate streams (JointState, PoseStamped, WrenchStamped at 500 Hz, /clock at 100 Hz) are collected as raw
bytes and decoded a batch at a time with the vectorised CDR decoders of ``messages.joint_states`` and
``messages.stamped_doubles``: an hour of states is arrays of floats, not millions of Python message objects. A
message that cannot be decoded is left out and counted per topic (``StreamSet.undecodable``), never a crash. Times
are header stamps in s; publish times (the recorder's copy of the header stamp) in ns.
"""

from __future__ import annotations

from array import array
from dataclasses import dataclass
from typing import cast

import numpy as np

from ..errors import InvalidInputError
from ..kinematics.rotations import rpy_from_quaternion
from ..messages import cdr
from ..messages.diagnostic_status import decode_diagnostic_array
from ..messages.joint_states import decode_joint_states_dropping_malformed
from ..messages.stamped_doubles import decode_stamped_doubles

BATCH_MESSAGES = 2_000  # raw messages held per topic before they are decoded together: 2,000 read a run as fast as
# 20,000 did (faster: the batch stays in cache) and hold ~60 MB less at once (seven 500 Hz topics pending)

JOINTS, POSE, WRENCH, STAMP = "joints", "pose", "wrench", "stamp"


JOINT_FIELDS = ("position", "velocity", "effort")


@dataclass(frozen=True)
class StreamKind:
    """How a topic is decoded: ``kind`` JOINTS (JointState, the columns ``names`` of the ``fields`` kept; a field
    not kept reads NaN), POSE (PoseStamped -> [x, y, z, roll, pitch, yaw] m, rad), WRENCH (WrenchStamped ->
    [force N, torque N m]) or STAMP (the header stamp, or a Clock's time, only)."""

    kind: str
    names: tuple = ()
    fields: tuple = JOINT_FIELDS


class _Rows:
    """Rows appended into arrays allocated once for the expected count (grown if it is passed): a long run's
    streams are never held twice, as joining parts at the end would."""

    def __init__(self, capacity: int, width: tuple):  # width: the shape of one row of values, () for none
        self.n = 0
        self.log = np.empty(capacity, np.int64)
        self.file = np.empty(capacity, np.int32)
        self.times = np.empty(capacity)
        self.values = np.empty((capacity, *width)) if width else None

    def append(self, log: np.ndarray, file_index: int, times: np.ndarray, values: np.ndarray | None = None) -> None:
        end = self.n + times.size
        if end > self.log.size:
            self._grow(max(end, int(1.5 * self.log.size) + 1024))
        self.log[self.n:end], self.file[self.n:end], self.times[self.n:end] = log, file_index, times
        if self.values is not None:
            self.values[self.n:end] = values
        self.n = end

    def _grow(self, capacity: int) -> None:
        for name in ("log", "file", "times", "values"):
            old = getattr(self, name)
            if old is not None:
                new = np.empty((capacity, *old.shape[1:]), old.dtype)
                new[:self.n] = old[:self.n]
                setattr(self, name, new)

    def in_order(self) -> tuple[np.ndarray, np.ndarray | None]:
        """(times, values) of the rows, file after file, each file's by log time (sorted only if they are not)."""
        log, file = self.log[:self.n], self.file[:self.n]
        times = self.times[:self.n]
        values = self.values[:self.n] if self.values is not None else None
        if ((np.diff(log) < 0) & (np.diff(file) == 0)).any():
            order = np.lexsort((log, file))
            times, values = times[order], values[order] if values is not None else None
        return times, values


class _Collector:
    """One topic's pending raw messages (with their log times, ns), decoded a batch at a time into rows; each
    decoded batch goes to the ``sink`` too, if there is one (in log-time order), and only the rows ``keep``
    selects (a mask of the stamps; None: all) are kept."""

    def __init__(self, spec: StreamKind, capacity: int, sink=None, keep=None):
        self.spec = spec
        self.sink, self.keep = sink, keep
        self.pending: list = []
        self.pending_log: list = []
        self.undecodable = 0
        self.file_index = 0  # the file being read: rows are ordered file after file, each by log time
        width = {JOINTS: (len(spec.fields), len(spec.names)), POSE: (6,), WRENCH: (6,), STAMP: ()}[spec.kind]
        self.rows = _Rows(capacity, width)

    def add(self, data: bytes, log_time: int) -> None:
        self.pending.append(data)
        self.pending_log.append(log_time)
        if len(self.pending) >= BATCH_MESSAGES:
            self.flush()

    def flush(self) -> None:
        if not self.pending:
            return
        batch, log = self.pending, np.asarray(self.pending_log, dtype=np.int64)
        self.pending, self.pending_log = [], []
        decode = {JOINTS: self._joints, POSE: self._pose, WRENCH: self._wrench, STAMP: self._stamps}[self.spec.kind]
        decode(batch, log)

    def _joints(self, batch: list, log: np.ndarray) -> None:
        batches, kept = decode_joint_states_dropping_malformed(batch, on_malformed=self._count)
        row = 0
        for part in batches:
            rows, row = kept[row:row + part.stamps.size], row + part.stamps.size
            if any(n not in part.names for n in self.spec.names):  # a message without one of the columns: left out
                continue
            columns = [part.names.index(n) for n in self.spec.names]
            values = np.stack([getattr(part, name)[:, columns] for name in self.spec.fields], axis=1)
            self._store(log[rows], part.stamps, values)

    def _pose(self, batch: list, log: np.ndarray) -> None:
        stamps, values, kept = self._doubles(batch, 7, "PoseStamped")
        norms = np.linalg.norm(values[:, 3:], axis=1, keepdims=True)
        good = np.isfinite(values).all(axis=1) & (norms[:, 0] > 0)
        poses = np.full((len(stamps), 6), np.nan)  # a pose that is not one stays NaN: the limit check reports it
        poses[good, :3] = values[good, :3]
        poses[good, 3:] = rpy_from_quaternion(values[good, 3:] / norms[good])
        self._store(log[kept], stamps, poses)

    def _wrench(self, batch: list, log: np.ndarray) -> None:
        stamps, values, kept = self._doubles(batch, 6, "WrenchStamped")
        self._store(log[kept], stamps, values)

    def _doubles(self, batch: list, count: int, what: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        stamps, _frames, values, kept, errors = decode_stamped_doubles(batch, count, what)
        self.undecodable += len(errors)
        return stamps, values, kept

    def _stamps(self, batch: list, log: np.ndarray) -> None:
        ns = [cdr.header_stamp_ns(data) for data in batch]
        good = np.array([t is not None for t in ns], dtype=bool)
        self.undecodable += int((~good).sum())
        self._store(log[good], np.array([t for t in ns if t is not None], dtype=np.int64) / 1e9)

    def _store(self, log: np.ndarray, times: np.ndarray, values: np.ndarray | None = None) -> None:
        """A decoded batch: to the sink in log-time order, then its kept rows to the topic's rows."""
        if self.sink is not None and times.size:
            if (np.diff(log) < 0).any():
                order = np.argsort(log, kind="stable")
                self.sink(*self._as_result(times[order], values[order] if values is not None else None))
            else:
                self.sink(*self._as_result(times, values))
        if self.keep is not None:
            mask = self.keep(times)
            log, times, values = log[mask], times[mask], values[mask] if values is not None else None
        self.rows.append(log, self.file_index, times, values)

    def _as_result(self, times: np.ndarray, values: np.ndarray | None) -> tuple:
        """(times, values) as ``result`` gives them (JOINTS: the columns by field; STAMP: the times alone)."""
        if self.spec.kind == STAMP:
            return (times,)
        if self.spec.kind == JOINTS:
            columns = cast(np.ndarray, values)  # JOINTS rows always have values
            missing = np.broadcast_to(np.nan, (times.size, len(self.spec.names)))  # read-only, no memory
            return times, {name: columns[:, self.spec.fields.index(name)] if name in self.spec.fields else missing
                           for name in JOINT_FIELDS}
        return times, values

    def _count(self, _reason: str) -> None:
        self.undecodable += 1

    def result(self):
        """JOINTS: (times [n] s, {"position", "velocity", "effort": [n, k]}); POSE and WRENCH: (times [n] s,
        values [n, 6]); STAMP: times [n] s. Rows file after file, each file's in log-time order (the order in which
        the recorder writes a topic; sorted here when a file holds it otherwise)."""
        self.flush()
        out = self._as_result(*self.rows.in_order())
        return out[0] if self.spec.kind == STAMP else out


@dataclass
class StreamSet:
    """What one pass over a run read: decoded streams by topic suffix, raw bytes of the topics kept raw, the
    publish times (ns) of the topics counted, and per topic the messages that could not be decoded."""

    decoded: dict
    raw: dict
    publish_ns: dict
    undecodable: dict


def topic_key(topic: str, keys) -> str | None:
    """The key (a topic name without namespace) that ``topic`` is, or ends with after a '/'."""
    for key in keys:
        if topic == key or topic.endswith("/" + key):
            return key
    return None


def read_streams(parts, decoded: dict, raw=(), counted=(), sinks=None, keep=None,
                 skip=()) -> tuple[StreamSet, list]:
    """Read every wanted topic of a run's files in one pass each.

    Args:
        parts: the run's files (RunReader each), in time order.
        decoded: {topic key: StreamKind}; a recorded topic matches a key it equals or ends with after a '/'
            (namespaced runs).
        raw: topic keys whose messages are kept as raw bytes (with their type name).
        counted: topic keys whose publish times are collected (ns), file after file.
        sinks: {decoded key: callable} called with every decoded batch of the topic, in order, as ``result``
            returns the whole topic (JOINTS: times, columns; POSE, WRENCH: times, values; STAMP: times): a
            whole-run figure computed as the run is read. Batches are each in log-time order, file after file.
        keep: {decoded key: callable(times [n] s) -> mask [n]}: only these rows of the topic are kept (e.g. the
            windows a figure needs); a key not in it keeps every row.
        skip: decoded keys whose messages are not read at all (their series come back empty): streams the
            caller does not use cost nothing to pass over.

    Returns:
        (StreamSet, per file {"file", "complete", "publish_ns": {key: publish times [n] (ns) in that file}}).
    """
    read = [key for key in decoded if key not in skip]
    expected = {key: 0 for key in decoded}
    for part in parts:
        for t in part.topics():
            key = topic_key(t.topic, read)
            if key is not None:
                expected[key] += t.message_count
    sinks, keep = sinks or {}, keep or {}
    collectors = {key: _Collector(spec, 0 if key in keep else expected[key], sinks.get(key), keep.get(key))
                  for key, spec in decoded.items()}
    raw_out: dict = {key: [] for key in raw}
    publish: dict = {key: [] for key in counted}
    files: list[dict] = []
    for part in parts:
        routes = {t.topic: (topic_key(t.topic, read), topic_key(t.topic, raw), topic_key(t.topic, counted))
                  for t in part.topics()}
        routes = {topic: keys for topic, keys in routes.items() if any(k is not None for k in keys)}
        for collector in collectors.values():
            collector.file_index = len(files)
        mine = _read_part(part, routes, collectors, raw_out, counted)
        for collector in collectors.values():
            collector.flush()  # a batch holds one file's messages
        for key, times in mine.items():
            publish[key].append(times)
        files.append({"file": part.path.name, "complete": part.complete, "publish_ns": mine})
    streams = StreamSet(
        decoded={key: c.result() for key, c in collectors.items()}, raw=raw_out,
        publish_ns={key: _joined(parts_ns) for key, parts_ns in publish.items()},
        undecodable={key: c.undecodable for key, c in collectors.items() if c.undecodable})
    return streams, files


def _joined(parts: list) -> np.ndarray:
    """Per-file int64 arrays as one (a single file's as it is: an hour of stamps is not copied)."""
    return parts[0] if len(parts) == 1 else np.concatenate(parts) if parts else np.empty(0, np.int64)


def _read_part(part, routes: dict, collectors: dict, raw_out: dict, counted) -> dict:
    """Route one file's messages, in the file's own order (several times faster than a merge by log time), to
    the collectors (which put each topic in log-time order) and the raw lists (sorted here by log time);
    returns the file's publish times per counted key (sorted by log time)."""
    mine: dict = {key: array("q") for key in counted}
    mine_log: dict = {key: array("q") for key in counted}
    raw_log: dict = {key: [] for key in raw_out}
    for topic, type_name, log_time, publish_time, data in part.records_in_file_order(set(routes)):
        d_key, r_key, c_key = routes[topic]
        if d_key is not None:
            collectors[d_key].add(data, log_time)
        if r_key is not None:
            raw_log[r_key].append((log_time, type_name, data))
        if c_key is not None:
            mine[c_key].append(publish_time)
            mine_log[c_key].append(log_time)
    for key, rows in raw_log.items():
        rows.sort(key=lambda row: row[0])
        raw_out[key].extend((type_name, data) for _log, type_name, data in rows)
    out = {}
    for key, times in mine.items():
        log = np.frombuffer(mine_log[key], dtype=np.int64)
        values = np.frombuffer(times, dtype=np.int64)
        out[key] = values[np.argsort(log, kind="stable")] if (np.diff(log) < 0).any() else values
    return out


def decode_diagnostics(messages) -> tuple[list, int]:
    """DiagnosticArray bytes -> (the status lists in order, how many arrays could not be decoded)."""
    arrays, bad = [], 0
    for data in messages:
        try:
            arrays.append(decode_diagnostic_array(data)[2])
        except InvalidInputError:
            bad += 1
    return arrays, bad
