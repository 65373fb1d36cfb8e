"""A run's recorded topics decoded into arrays in one pass over its MCAP (pure: no rclpy, no mcap_ros2).

The high-rate streams (JointState, PoseStamped, WrenchStamped at 500 Hz, /clock at 100 Hz) are collected as raw
bytes and decoded a batch at a time with the vectorised CDR decoders of ``messages.cdr``: an hour of states is
arrays of floats, not millions of Python message objects. A message that cannot be decoded is left out and
counted per topic (``StreamSet.undecodable``), never a crash. Times are header stamps in s; publish times
(the recorder's copy of the header stamp) in ns.
"""

from __future__ import annotations

from array import array
from dataclasses import dataclass, field

import numpy as np

from ..errors import InvalidInputError
from ..kinematics.rotations import rpy_from_quaternion
from ..messages import cdr

BATCH_MESSAGES = 20_000  # raw messages held per topic before they are decoded together

JOINTS, POSE, WRENCH, STAMP = "joints", "pose", "wrench", "stamp"


@dataclass(frozen=True)
class StreamKind:
    """How a topic is decoded: ``kind`` JOINTS (JointState, the columns ``names``), POSE (PoseStamped -> [x, y, z,
    roll, pitch, yaw] m, rad), WRENCH (WrenchStamped -> [force N, torque N m]) or STAMP (the header stamp, or a
    Clock's time, only)."""

    kind: str
    names: tuple = ()


@dataclass
class _Collector:
    """One topic's pending raw messages (with their log times, ns) and its decoded parts."""

    spec: StreamKind
    pending: list = field(default_factory=list)
    pending_log: list = field(default_factory=list)
    log_times: list = field(default_factory=list)
    times: list = field(default_factory=list)
    values: list = field(default_factory=list)
    undecodable: int = 0
    file_index: int = 0  # the file being read: rows are ordered file after file, each by log time
    file_indices: list = field(default_factory=list)

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
        before = len(self.log_times)
        decode(batch, log)
        self.file_indices += [np.full(rows.size, self.file_index) for rows in self.log_times[before:]]

    def _joints(self, batch: list, log: np.ndarray) -> None:
        batches, kept = cdr.decode_joint_states_dropping_malformed(batch, on_malformed=self._count)
        row = 0
        for part in batches:
            rows, row = kept[row:row + part.stamps.size], row + part.stamps.size
            if any(n not in part.names for n in self.spec.names):  # a message without one of the columns: left out
                continue
            columns = [part.names.index(n) for n in self.spec.names]
            self.log_times.append(log[rows])
            self.times.append(part.stamps)
            self.values.append(np.stack([part.position[:, columns], part.velocity[:, columns],
                                         part.effort[:, columns]]))

    def _pose(self, batch: list, log: np.ndarray) -> None:
        stamps, values = self._doubles(batch, log, 7, "PoseStamped")
        norms = np.linalg.norm(values[:, 3:], axis=1, keepdims=True)
        good = np.isfinite(values).all(axis=1) & (norms[:, 0] > 0)
        poses = np.full((len(stamps), 6), np.nan)  # a pose that is not one stays NaN: the limit check reports it
        poses[good, :3] = values[good, :3]
        poses[good, 3:] = rpy_from_quaternion(values[good, 3:] / norms[good])
        self.times.append(stamps)
        self.values.append(poses)

    def _wrench(self, batch: list, log: np.ndarray) -> None:
        stamps, values = self._doubles(batch, log, 6, "WrenchStamped")
        self.times.append(stamps)
        self.values.append(values)

    def _doubles(self, batch: list, log: np.ndarray, count: int, what: str) -> tuple[np.ndarray, np.ndarray]:
        stamps, _frames, values, kept, errors = cdr.decode_stamped_doubles(batch, count, what)
        self.undecodable += len(errors)
        self.log_times.append(log[kept])
        return stamps, values

    def _stamps(self, batch: list, log: np.ndarray) -> None:
        ns = [cdr.header_stamp_ns(data) for data in batch]
        good = np.array([t is not None for t in ns], dtype=bool)
        self.undecodable += int((~good).sum())
        self.log_times.append(log[good])
        self.times.append(np.array([t for t in ns if t is not None], dtype=np.int64) / 1e9)

    def _count(self, _reason: str) -> None:
        self.undecodable += 1

    def result(self):
        """JOINTS: (times [n] s, {"position", "velocity", "effort": [n, k]}); POSE and WRENCH: (times [n] s,
        values [n, 6]); STAMP: times [n] s. Rows file after file, each file's in log-time order (the order in which
        the recorder writes a topic; sorted here when a file holds it otherwise)."""
        self.flush()
        log = np.concatenate(self.log_times) if self.log_times else np.empty(0, np.int64)
        files = np.concatenate(self.file_indices) if self.file_indices else np.empty(0, int)
        order = np.lexsort((log, files)) if ((np.diff(log) < 0) & (np.diff(files) == 0)).any() else slice(None)
        times = (np.concatenate(self.times) if self.times else np.empty(0))[order]
        if self.spec.kind == STAMP:
            return times
        if self.spec.kind == JOINTS:
            k = len(self.spec.names)
            stacked = (np.concatenate(self.values, axis=1) if self.values else np.empty((3, 0, k)))[:, order]
            return times, {"position": stacked[0], "velocity": stacked[1], "effort": stacked[2]}
        return times, (np.concatenate(self.values) if self.values else np.empty((0, 6)))[order]


@dataclass
class StreamSet:
    """What one pass over a run read: decoded streams by topic suffix, raw bytes of the topics kept raw, the
    publish times (ns) of the topics counted, and per topic the messages that could not be decoded."""

    decoded: dict
    raw: dict
    publish_ns: dict
    undecodable: dict


def _topic_key(topic: str, keys) -> str | None:
    """The key (a topic name without namespace) that ``topic`` is, or ends with after a '/'."""
    for key in keys:
        if topic == key or topic.endswith("/" + key):
            return key
    return None


def read_streams(parts, decoded: dict, raw=(), counted=()) -> tuple[StreamSet, list]:
    """Read every wanted topic of a run's files in one pass each.

    Args:
        parts: the run's files (RunReader each), in time order.
        decoded: {topic key: StreamKind}; a recorded topic matches a key it equals or ends with after a '/'
            (namespaced runs).
        raw: topic keys whose messages are kept as raw bytes (with their type name).
        counted: topic keys whose publish times are collected (ns), file after file.

    Returns:
        (StreamSet, per file {"file", "complete", "publish_ns": {key: publish times [n] (ns) in that file}}).
    """
    collectors = {key: _Collector(spec) for key, spec in decoded.items()}
    raw_out: dict = {key: [] for key in raw}
    publish: dict = {key: [] for key in counted}
    files: list[dict] = []
    for part in parts:
        routes = {t.topic: (_topic_key(t.topic, decoded), _topic_key(t.topic, raw), _topic_key(t.topic, counted))
                  for t in part.topics()}
        routes = {topic: keys for topic, keys in routes.items() if any(k is not None for k in keys)}
        for collector in collectors.values():
            collector.file_index = len(files)
        mine = _read_part(part, routes, collectors, raw_out, counted)
        for collector in collectors.values():
            collector.flush()
        for key, times in mine.items():
            publish[key].append(times)
        files.append({"file": part.path.name, "complete": part.complete, "publish_ns": mine})
    streams = StreamSet(
        decoded={key: c.result() for key, c in collectors.items()}, raw=raw_out,
        publish_ns={key: np.concatenate(parts_ns) if parts_ns else np.empty(0, np.int64)
                    for key, parts_ns in publish.items()},
        undecodable={key: c.undecodable for key, c in collectors.items() if c.undecodable})
    return streams, files


def _read_part(part, routes: dict, collectors: dict, raw_out: dict, counted) -> dict:
    """Route one file's messages, in the file's own order (several times faster than a merge by log time), to
    the collectors (which put each topic in log-time order) and the raw lists (sorted here by log time);
    returns the file's publish times per counted key (sorted by log time)."""
    mine: dict = {key: array("q") for key in counted}
    mine_log: dict = {key: array("q") for key in counted}
    raw_log: dict = {key: [] for key in raw_out}
    for message in part.messages(list(routes), log_time_order=False):
        d_key, r_key, c_key = routes[message.topic]
        if d_key is not None:
            collectors[d_key].add(message.data, message.log_time)
        if r_key is not None:
            raw_log[r_key].append((message.log_time, message.type_name, message.data))
        if c_key is not None:
            mine[c_key].append(message.publish_time)
            mine_log[c_key].append(message.log_time)
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
            arrays.append(cdr.decode_diagnostic_array(data)[2])
        except InvalidInputError:
            bad += 1
    return arrays, bad
