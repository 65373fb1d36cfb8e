"""rosbag2-compatible MCAP writer with its own writer thread (no rclpy).

``McapRunWriter.submit`` is called from the ROS executor thread and only puts
a tuple on a queue; a writer thread drains it every 20 ms into MCAP records:
profile ``ros2``, one schema per type (``pkg/msg/Type``, ``ros2msg``, full
definition text), one channel per topic (``cdr``, ``offered_qos_profiles`` and
``topic_type_hash`` metadata), zstd chunks with chunk and message indexes,
statistics, and at the end a ``rosbag2`` metadata record with the bag's
``serialized_metadata`` (version 9) as ``ros2 bag`` writes it
(stewart_vibration.mcap_log.bag_metadata; the recorder also writes it as the
bag directory's ``metadata.yaml``).

Crash safety: the file is unbuffered (each record group goes to the OS in one
``write``), a chunk is written as soon as it holds ``chunk_size`` bytes or has
been open ``flush_period_s`` seconds (checked by the writer thread at least
every ``flush_period_s / 4``), so after a SIGKILL every chunk completed before
it is on disk, whole, with its message indexes. ``stewart-vibration
mcap-recover`` (mcap_log.recover) rebuilds a complete, indexed file from them.
Worst-case loss: the open chunk (at most ``chunk_size`` bytes and about
``flush_period_s`` of recording) plus whatever was still queued.

Write errors: a failed write (a full disk, ENOSPC; an I/O error, EIO; a quota) or a file that no
longer has its name (its folder removed or replaced: checked at every chunk) stops the recording at
once. The file is cut back to its last whole record, so what was written stays readable (every chunk
before the failure; ``mcap-recover`` rebuilds its summary), ``McapRunWriter.failure`` says what went
wrong, and every message submitted after it is counted in ``WriterStats.lost_after_failure``.
"""

from __future__ import annotations

import collections
import errno
import os
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, cast

from mcap.writer import CompressionType, IndexType, Writer

from ..messages.cdr import header_stamp_ns
from .bag_metadata import BagFile, TopicCount, bag_metadata, dump_bag_metadata
from .msg_definitions import full_message_definition, has_header_first

LIBRARY = "stewart_vibration mcap_recorder (python mcap writer)"
_STOP = object()
DRAIN_PERIOD_S = 0.02  # the writer thread takes the queued messages this often


@dataclass(frozen=True)
class WriteFailure:
    """Why a recording stopped: ``code`` the errno name (ENOSPC, EIO, ENOENT for a file that lost its
    name, ...), ``reason`` one line, ``good_bytes`` the whole-record prefix the file keeps."""

    code: str
    reason: str
    good_bytes: int


class FileWriteError(OSError):
    """A write to the recording failed; the file was cut back to ``good_bytes`` (its whole records)."""

    def __init__(self, failure: WriteFailure):
        super().__init__(failure.reason)
        self.failure = failure


class _UnbufferedSink:
    """Write-through file for mcap.Writer: every record group reaches the OS at once. A failed write cuts the
    file back to where the group began (a partly written chunk would hide every later record from readers)
    and raises FileWriteError."""

    def __init__(self, path: Path):
        self.path = path
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        self._inode = os.fstat(self._fd).st_ino
        self._pos = 0

    def write(self, data) -> int:
        view = memoryview(data)
        start = self._pos
        try:
            while view:
                n = os.write(self._fd, view)
                view = view[n:]
                self._pos += n
        except OSError as exc:
            self._fail(exc, start)
        return len(data)

    def check_name(self) -> None:
        """FileWriteError (ENOENT) when the path no longer names the file being written (folder removed,
        file deleted or replaced): the writes would go to a file nobody can find."""
        try:
            same = os.stat(self.path).st_ino == self._inode
        except OSError:
            same = False
        if not same:
            raise FileWriteError(WriteFailure("ENOENT", f"{self.path} no longer names the file being written (its "
                                              "folder or the file was removed or replaced)", self._pos))

    def _fail(self, exc: OSError, good: int) -> None:
        try:
            os.ftruncate(self._fd, good)
            self._pos = good
        except OSError:
            pass
        code = errno.errorcode.get(exc.errno or 0, "EIO")
        raise FileWriteError(WriteFailure(code, f"writing {self.path} failed at {good:,} bytes: "
                                          f"{exc.strerror or exc} ({code})", self._pos)) from exc

    def tell(self) -> int:
        return self._pos

    def flush(self) -> None:
        pass

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1


@dataclass
class _Topic:
    name: str
    type_name: str
    qos_yaml: str
    type_hash: str
    channel_id: int
    stamped: bool
    count: int = 0


@dataclass
class WriterStats:
    """Counters of one recording; ``dropped`` counts messages refused because the queue was full."""

    received: int = 0
    written: int = 0
    dropped: int = 0
    max_backlog: int = 0
    chunks_flushed_by_time: int = 0
    lost_after_failure: int = 0  # submitted after a write failure (never written)
    per_topic: dict = field(default_factory=dict)

    @property
    def backlog(self) -> int:
        """Messages received but neither written nor dropped yet (still queued)."""
        return self.received - self.written - self.dropped


class BagFileWriter:
    """Synchronous rosbag2-layout MCAP file: schemas by type, channels by topic, bag metadata at the end.

    Used by the recorder's writer thread and by ``mcap-recover``. The schema text
    is the installed full ``ros2msg`` definition unless given (recovery keeps the
    recorded one). ``finish`` writes the ``rosbag2`` metadata record, the summary
    (statistics, chunk/message indexes) and closes the file.
    """

    def __init__(self, path: str | Path, chunk_size: int = 256 * 1024, compression: str = "zstd",
                 library: str = LIBRARY):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._topics: dict[str, _Topic] = {}
        self._schemas: dict[str, int] = {}
        self._sink = _UnbufferedSink(self.path)
        self._writer = Writer(
            cast(IO[bytes], self._sink),  # duck-typed: write, tell, flush
            chunk_size=int(chunk_size),
            compression=CompressionType.ZSTD if compression == "zstd" else CompressionType.NONE,
            index_types=IndexType.ALL,
            enable_crcs=True,
            enable_data_crcs=True,  # DataEnd carries the data section's CRC: `report` verifies it
        )
        self._writer.start(profile="ros2", library=library)
        self._t0: int | None = None
        self._t1 = 0
        self._finished = False

    def add_topic(self, topic: str, type_name: str, qos_yaml: str, type_hash: str = "",
                  schema_text: str | None = None, schema_encoding: str = "ros2msg") -> None:
        """Schema (once per type) and channel (once per topic) with rosbag2's channel metadata."""
        if topic in self._topics:
            return
        schema_id = self._schemas.get(type_name)
        if schema_id is None:
            text = full_message_definition(type_name) if schema_text is None else schema_text
            schema_id = self._writer.register_schema(type_name, schema_encoding, text.encode("utf-8"))
            self._schemas[type_name] = schema_id
        channel_id = self._writer.register_channel(
            topic, "cdr", schema_id, {"offered_qos_profiles": qos_yaml, "topic_type_hash": type_hash}
        )
        self._topics[topic] = _Topic(topic, type_name, qos_yaml, type_hash, channel_id, has_header_first(type_name))

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        """Add a metadata record ``name`` with string key/values ``data``."""
        self._writer.add_metadata(name, data)

    def add_attachment(self, a) -> None:
        """Copy an mcap.records.Attachment."""
        self._writer.add_attachment(a.create_time, a.log_time, a.name, a.media_type, a.data)

    def write(self, topic: str, log_time_ns: int, data: bytes, publish_time_ns: int | None = None,
              sequence: int | None = None) -> int:
        """One message; publish_time defaults to header.stamp (stamped types) or log time. Returns its count."""
        t = self._topics[topic]
        if publish_time_ns is None:
            stamp = header_stamp_ns(data) if t.stamped else None
            publish_time_ns = log_time_ns if stamp is None else stamp
        t.count += 1
        log_time_ns = int(log_time_ns)
        if self._t0 is None or log_time_ns < self._t0:
            self._t0 = log_time_ns
        self._t1 = max(self._t1, log_time_ns)
        self._writer.add_message(
            t.channel_id,
            log_time=log_time_ns,
            data=bytes(data),
            publish_time=int(publish_time_ns),
            sequence=t.count if sequence is None else int(sequence),
        )
        return t.count

    def flush(self) -> None:
        """Close the open chunk and write it (with its message indexes) to the file; FileWriteError if the
        write fails or the file lost its name."""
        self._sink.check_name()
        self._writer.flush()

    def bag_file(self) -> BagFile:
        """This file as one entry of a bag's metadata (name relative to its directory)."""
        return BagFile(
            self.path.name,
            self._t0 or 0,
            self._t1,
            [TopicCount(t.name, t.type_name, t.qos_yaml, t.type_hash, t.count) for t in self._topics.values()],
        )

    def bag_metadata_yaml(self) -> str:
        """rosbag2 BagMetadata (version 9) of this file, as ``ros2 bag`` embeds it (``serialized_metadata``)."""
        return dump_bag_metadata(bag_metadata([self.bag_file()]), root=False)

    def abort(self) -> None:
        """Close the file without a summary (the caller deletes it)."""
        self._finished = True
        self._sink.close()

    def finish(self) -> BagFile:
        """Write the rosbag2 metadata record and the summary, close the file."""
        if not self._finished:
            self._finished = True
            self._writer.add_metadata("rosbag2", {"serialized_metadata": self.bag_metadata_yaml()})
            self._writer.finish()
            self._sink.close()
        return self.bag_file()


class McapRunWriter:
    """One MCAP file being written by a background thread (a BagFileWriter)."""

    def __init__(
        self,
        path: str | Path,
        chunk_size: int = 256 * 1024,
        flush_period_s: float = 0.5,
        max_queue: int = 1_000_000,
        compression: str = "zstd",
    ):
        self.stats = WriterStats()
        # producers append to a deque (thread-safe, no lock handoff); the writer thread drains it every
        # DRAIN_PERIOD_S instead of waking once per message (2,600 msg/s in a suite run)
        self._queue: collections.deque = collections.deque()
        self._wake = threading.Event()
        self._max_queue = int(max_queue)
        self._flush_period_s = float(flush_period_s)
        self._file = BagFileWriter(path, chunk_size=chunk_size, compression=compression)
        self.path = self._file.path
        self._closed = False
        self._error: BaseException | None = None
        self.failure: WriteFailure | None = None  # set by the writer thread when a write failed
        self._thread = threading.Thread(target=self._run, name="mcap-writer", daemon=True)
        self._thread.start()

    # -- producer side (any thread) -------------------------------------------------
    def add_topic(self, topic: str, type_name: str, qos_yaml: str, type_hash: str = "") -> None:
        """Declare a topic before its first message (ordered with messages through the queue)."""
        self._queue.append(("topic", topic, type_name, qos_yaml, type_hash))

    def submit(self, topic: str, log_time_ns: int, data: bytes) -> bool:
        """Queue one serialized message; False (and counted as dropped) when the queue is full."""
        stats = self.stats
        if self.failure is not None:
            stats.lost_after_failure += 1
            return False
        stats.received += 1
        backlog = stats.received - stats.written - stats.dropped
        if backlog > stats.max_backlog:
            stats.max_backlog = backlog
        if backlog > self._max_queue:
            stats.dropped += 1
            return False
        self._queue.append((topic, log_time_ns, data))
        return True

    def close(self) -> WriterStats:
        """Drain the queue, write the summary and the rosbag2 metadata, close the file. After a write failure
        the file is closed as it was cut (``failure`` says why; no summary: ``mcap-recover`` rebuilds it)."""
        if not self._closed:
            self._closed = True
            self._queue.append(_STOP)
            self._wake.set()
            self._thread.join()
            if self.failure is None and self._error is None:
                try:
                    self._file.finish()
                except FileWriteError as exc:
                    self.failure = exc.failure
            if self.failure is not None:
                self._file.abort()
        if self._error is not None:
            raise self._error
        return self.stats

    def bag_file(self) -> BagFile:
        """The file's entry for the bag directory's metadata.yaml (complete after close)."""
        return self._file.bag_file()

    def bag_metadata_yaml(self) -> str:
        """rosbag2 BagMetadata (version 9) of the file so far, as ``ros2 bag`` embeds it."""
        return self._file.bag_metadata_yaml()

    # -- writer thread ----------------------------------------------------------------
    def _run(self) -> None:
        last_flush = time.monotonic()
        pending = 0
        queue_ = self._queue
        try:
            while True:
                self._wake.wait(DRAIN_PERIOD_S)
                while queue_:
                    item = queue_.popleft()
                    if item is _STOP:
                        return
                    if item[0] == "topic" and len(item) == 5:
                        self._file.add_topic(*item[1:])
                    else:
                        topic, log_time_ns, data = item
                        self.stats.per_topic[topic] = self._file.write(topic, log_time_ns, data)
                        self.stats.written += 1
                        pending += 1
                now = time.monotonic()
                if pending and now - last_flush >= self._flush_period_s:
                    self._file.flush()
                    self.stats.chunks_flushed_by_time += 1
                    pending = 0
                    last_flush = now
                elif not pending:
                    last_flush = now
        except FileWriteError as exc:  # the file keeps its whole records; the node reports it at once
            self.failure = exc.failure
            self.stats.lost_after_failure += len(queue_)
            queue_.clear()
        except BaseException as exc:  # surfaced by close()
            self._error = exc
