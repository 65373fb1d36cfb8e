"""rosbag2-compatible MCAP writer with its own writer thread (no rclpy).

``McapRunWriter.submit`` is called from the ROS executor thread and only puts
a tuple on a queue; a writer thread turns the queue into MCAP records:
profile ``ros2``, one schema per type (``pkg/msg/Type``, ``ros2msg``, full
definition text), one channel per topic (``cdr``, ``offered_qos_profiles`` and
``topic_type_hash`` metadata), zstd chunks with chunk and message indexes,
statistics, and at the end a ``rosbag2`` metadata record with the bag's
``serialized_metadata`` (version 9) as ``ros2 bag`` writes it.

Crash safety: the file is unbuffered, a chunk is written as soon as it holds
``chunk_size`` bytes or has been open ``flush_period_s`` seconds, so after a
SIGKILL everything up to the last completed chunk is readable (a reader scans
the data section without the summary). Worst-case loss: the open chunk
(at most ``chunk_size`` bytes of messages and at most ``flush_period_s`` of
recording) plus whatever was still queued.
"""

from __future__ import annotations

import os
import queue
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import yaml
from mcap.writer import CompressionType, IndexType, Writer

from .cdr import header_stamp_ns
from .msg_definitions import full_message_definition, has_header_first

LIBRARY = "stewart_vibration mcap_recorder (python mcap writer)"
ROS_DISTRO = "jazzy"
_STOP = object()


class _UnbufferedSink:
    """Write-through file for mcap.Writer: every record group reaches the OS at once."""

    def __init__(self, path: Path):
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        self._pos = 0

    def write(self, data) -> int:
        view = memoryview(data)
        while view:
            n = os.write(self._fd, view)
            view = view[n:]
        self._pos += len(data)
        return len(data)

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
    per_topic: dict = field(default_factory=dict)

    @property
    def backlog(self) -> int:
        return self.received - self.written - self.dropped


class McapRunWriter:
    """One MCAP file being written by a background thread."""

    def __init__(
        self,
        path: str | Path,
        chunk_size: int = 256 * 1024,
        flush_period_s: float = 0.5,
        max_queue: int = 1_000_000,
        compression: str = "zstd",
    ):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.stats = WriterStats()
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self._max_queue = int(max_queue)
        self._flush_period_s = float(flush_period_s)
        self._topics: dict[str, _Topic] = {}
        self._schemas: dict[str, int] = {}
        self._sink = _UnbufferedSink(self.path)
        self._writer = Writer(
            self._sink,
            chunk_size=int(chunk_size),
            compression=CompressionType.ZSTD if compression == "zstd" else CompressionType.NONE,
            index_types=IndexType.ALL,
        )
        self._writer.start(profile="ros2", library=LIBRARY)
        self._t0: int | None = None
        self._t1 = 0
        self._closed = False
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="mcap-writer", daemon=True)
        self._thread.start()

    # -- producer side (any thread) -------------------------------------------------
    def add_topic(self, topic: str, type_name: str, qos_yaml: str, type_hash: str = "") -> None:
        """Declare a topic before its first message (ordered with messages through the queue)."""
        self._queue.put(("topic", topic, type_name, qos_yaml, type_hash))

    def submit(self, topic: str, log_time_ns: int, data: bytes) -> bool:
        """Queue one serialized message; False (and counted as dropped) when the queue is full."""
        stats = self.stats
        stats.received += 1
        backlog = stats.received - stats.written - stats.dropped
        if backlog > stats.max_backlog:
            stats.max_backlog = backlog
        if backlog > self._max_queue:
            stats.dropped += 1
            return False
        self._queue.put((topic, log_time_ns, data))
        return True

    def close(self) -> WriterStats:
        """Drain the queue, write the summary and the rosbag2 metadata, close the file."""
        if not self._closed:
            self._closed = True
            self._queue.put(_STOP)
            self._thread.join()
            self._write_bag_metadata()
            self._writer.finish()
            self._sink.close()
        if self._error is not None:
            raise self._error
        return self.stats

    # -- writer thread ----------------------------------------------------------------
    def _run(self) -> None:
        last_flush = time.monotonic()
        pending = 0
        try:
            while True:
                try:
                    item = self._queue.get(timeout=self._flush_period_s / 4)
                except queue.Empty:
                    item = None
                if item is _STOP:
                    return
                if item is not None:
                    if item[0] == "topic" and len(item) == 5:
                        self._register(*item[1:])
                    else:
                        self._write(*item)
                        pending += 1
                now = time.monotonic()
                if pending and now - last_flush >= self._flush_period_s:
                    self._writer.flush()
                    self.stats.chunks_flushed_by_time += 1
                    pending = 0
                    last_flush = now
                elif not pending:
                    last_flush = now
        except BaseException as exc:  # surfaced by close()
            self._error = exc

    def _register(self, topic: str, type_name: str, qos_yaml: str, type_hash: str) -> None:
        if topic in self._topics:
            return
        schema_id = self._schemas.get(type_name)
        if schema_id is None:
            text = full_message_definition(type_name)
            schema_id = self._writer.register_schema(type_name, "ros2msg", text.encode("utf-8"))
            self._schemas[type_name] = schema_id
        channel_id = self._writer.register_channel(
            topic,
            "cdr",
            schema_id,
            {"offered_qos_profiles": qos_yaml, "topic_type_hash": type_hash},
        )
        self._topics[topic] = _Topic(
            topic, type_name, qos_yaml, type_hash, channel_id, has_header_first(type_name)
        )

    def _write(self, topic: str, log_time_ns: int, data: bytes) -> None:
        t = self._topics[topic]
        publish = header_stamp_ns(data) if t.stamped else None
        t.count += 1
        if self._t0 is None or log_time_ns < self._t0:
            self._t0 = int(log_time_ns)
        self._t1 = max(self._t1, int(log_time_ns))
        self._writer.add_message(
            t.channel_id,
            log_time=int(log_time_ns),
            data=bytes(data),
            publish_time=int(log_time_ns if publish is None else publish),
            sequence=t.count,
        )
        self.stats.written += 1
        self.stats.per_topic[topic] = t.count

    def _write_bag_metadata(self) -> None:
        self._writer.add_metadata("rosbag2", {"serialized_metadata": self.bag_metadata_yaml()})

    def bag_metadata_yaml(self) -> str:
        """rosbag2 BagMetadata (version 9) as YAML, as ``ros2 bag`` stores it in the file."""
        start, end = (self._t0 or 0), self._t1
        duration = max(0, end - start)
        topics = [
            {
                "topic_metadata": {
                    "name": t.name,
                    "type": t.type_name,
                    "serialization_format": "cdr",
                    "offered_qos_profiles": t.qos_yaml,
                    "type_description_hash": t.type_hash,
                },
                "message_count": t.count,
            }
            for t in self._topics.values()
        ]
        count = sum(t.count for t in self._topics.values())
        meta = {
            "version": 9,
            "storage_identifier": "mcap",
            "duration": {"nanoseconds": duration},
            "starting_time": {"nanoseconds_since_epoch": start},
            "message_count": count,
            "topics_with_message_count": topics,
            "compression_format": "",
            "compression_mode": "",
            "relative_file_paths": [self.path.name],
            "files": [
                {
                    "path": self.path.name,
                    "starting_time": {"nanoseconds_since_epoch": start},
                    "duration": {"nanoseconds": duration},
                    "message_count": count,
                }
            ],
            "custom_data": {},
            "ros_distro": ROS_DISTRO,
        }
        return yaml.safe_dump(meta, sort_keys=False)
