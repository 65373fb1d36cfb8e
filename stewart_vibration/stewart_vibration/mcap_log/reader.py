"""Read our (or any rosbag2) MCAP runs: topic summary, raw messages in log-time order, decoding.

Works on complete files (summary and indexes) and on files cut short by a
crash (linear scan of the data section up to the last complete record).
``open_run`` is the entry point of the CLI and the replay node: it accepts a
bag directory too and refuses a truncated file (McapFileError, pointing at
``mcap-recover``); RunReader itself refuses only missing, empty and non-MCAP files.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, ChunkIndex, Message, Metadata, Schema
from mcap.stream_reader import StreamReader, get_chunk_data_stream

from .bag_metadata import BagFile, TopicCount
from .files import McapFileError, check_readable, run_files, truncated_error
from .integrity import verify_mcap

_RECORD = struct.Struct("<BQ")  # an MCAP record's opcode and content length
_MESSAGE = struct.Struct("<HIQQ")  # a Message record's channel id, sequence, log time and publish time (ns)
_MESSAGE_OPCODE = 0x05
SORTED_IN_MEMORY = 100_000  # topics with at most this many messages are read chunk by chunk and sorted in memory


@dataclass(frozen=True)
class TopicSummary:
    """One channel of a run."""

    topic: str
    type_name: str
    message_count: int
    offered_qos_profiles: str
    schema_text: str


@dataclass(frozen=True)
class RawMessage:
    """One recorded message: times in ns, serialized CDR bytes."""

    topic: str
    type_name: str
    log_time: int
    publish_time: int
    data: bytes


class RunReader:
    """Random access when the file has a summary, else one linear scan (crash-truncated files)."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.complete = False
        self.truncated = False
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self.metadata: dict[str, dict[str, str]] = {}
        self.profile = ""
        self.start_ns = 0  # log time of the first and last message (ns; 0 without messages)
        self.end_ns = 0
        self._counts: dict[int, int] = {}
        self._messages: list[Message] | None = None
        self._chunk_indexes: list[ChunkIndex] = []  # in file order
        self._load()

    def _load(self) -> None:
        check_readable(self.path)
        with open(self.path, "rb") as f:
            reader = make_reader(f)
            try:
                self.profile = reader.get_header().profile
                summary = reader.get_summary()
            except McapError:
                summary = None
            if summary is not None and summary.statistics is not None:
                self.complete = True
                self.schemas = dict(summary.schemas)
                self.channels = dict(summary.channels)
                self._counts = dict(summary.statistics.channel_message_counts)
                self.start_ns = int(summary.statistics.message_start_time)
                self._chunk_indexes = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
                self.end_ns = int(summary.statistics.message_end_time)
                for name, data in ((m.name, m.metadata) for m in reader.iter_metadata()):
                    self.metadata[name] = dict(data)
                return
        self._scan()

    def _scan(self) -> None:
        """Linear scan; stops quietly at a truncated record (crash), setting ``truncated``."""
        messages: list[Message] = []
        with open(self.path, "rb") as f:
            try:
                for record in StreamReader(f, skip_magic=False).records:
                    if isinstance(record, Schema):
                        self.schemas[record.id] = record
                    elif isinstance(record, Channel):
                        self.channels[record.id] = record
                    elif isinstance(record, Message):
                        messages.append(record)
                        self._counts[record.channel_id] = self._counts.get(record.channel_id, 0) + 1
                    elif isinstance(record, Metadata):
                        self.metadata[record.name] = dict(record.metadata)
                    elif hasattr(record, "profile"):
                        self.profile = record.profile
            except Exception:  # noqa: BLE001 - any parse error past the last good record
                self.truncated = True
        messages.sort(key=lambda m: m.log_time)
        self._messages = messages
        if messages:
            self.start_ns, self.end_ns = int(messages[0].log_time), int(messages[-1].log_time)

    def check_complete(self) -> None:
        """Raise McapFileError when the file was cut short (no summary), with how much is readable."""
        if self.truncated:
            raise truncated_error(self.path)

    def topics(self) -> list[TopicSummary]:
        """Every channel with its type, message count, QoS YAML and schema text."""
        out = []
        for cid, ch in sorted(self.channels.items()):
            schema = self.schemas.get(ch.schema_id)
            out.append(
                TopicSummary(
                    ch.topic,
                    schema.name if schema else "",
                    int(self._counts.get(cid, 0)),
                    ch.metadata.get("offered_qos_profiles", ""),
                    schema.data.decode("utf-8") if schema else "",
                )
            )
        return out

    def message_count(self) -> int:
        """Number of messages in the file, all channels (the summary's statistics, or counted by the scan)."""
        return int(sum(self._counts.values()))

    def _raw(self, msg: Message) -> RawMessage:
        ch = self.channels[msg.channel_id]
        schema = self.schemas.get(ch.schema_id)
        return RawMessage(
            ch.topic, schema.name if schema else "", msg.log_time, msg.publish_time, msg.data
        )

    def messages(self, topics: list[str] | None = None, log_time_order: bool = True) -> Iterator[RawMessage]:
        """Raw messages, optionally only ``topics``: in log-time order, or with ``log_time_order`` False in the
        order they are in the file (chunk after chunk; no merge across chunks, several times faster)."""
        wanted = set(topics) if topics is not None else None
        if self._messages is not None:
            for m in self._messages:
                if wanted is None or self.channels[m.channel_id].topic in wanted:
                    yield self._raw(m)
            return
        if not log_time_order and self._chunk_indexes:
            yield from self._chunk_after_chunk(wanted)
            return
        if wanted is not None and self._chunk_indexes and self._count_of(wanted) <= SORTED_IN_MEMORY:
            # a few messages spread over a long file: every chunk is parsed either way, and the library's merge
            # parses each record into objects first (10 s for the diagnostics of a 4-minute run)
            yield from sorted(self._chunk_after_chunk(wanted), key=lambda m: m.log_time)
            return
        with open(self.path, "rb") as f:
            reader = make_reader(f)
            for _schema, _channel, message in reader.iter_messages(
                topics=list(wanted) if wanted is not None else None, log_time_order=log_time_order
            ):
                yield self._raw(message)

    def _count_of(self, topics: set[str]) -> int:
        """Messages of ``topics`` in the file."""
        return sum(n for cid, n in self._counts.items() if cid in self.channels and self.channels[cid].topic in topics)

    def _chunk_after_chunk(self, wanted: set[str] | None) -> Iterator[RawMessage]:
        """The messages of ``wanted`` topics in file order (``records_in_file_order``)."""
        for topic, type_name, log_time, publish_time, data in self.records_in_file_order(wanted):
            yield RawMessage(topic, type_name, log_time, publish_time, data)

    def records_in_file_order(self, wanted: set[str] | None) -> Iterator[tuple[str, str, int, int, bytes]]:
        """(topic, type name, log time ns, publish time ns, serialized bytes) of every message of ``wanted``
        topics (None: all), chunk after chunk in file order, one chunk in memory at a time.

        The mcap library's unordered read decompresses every chunk before it yields the first message, and its
        record objects cost several microseconds each: a long run is read here from the chunk's bytes (the
        Message record layout of the MCAP specification). A file without chunk indexes (cut short, or not
        chunked) is read through ``messages``.
        """
        if not self._chunk_indexes:
            for m in self.messages(list(wanted) if wanted is not None else None):
                yield m.topic, m.type_name, m.log_time, m.publish_time, m.data
            return
        names = {cid: (ch.topic, self.schemas[ch.schema_id].name if ch.schema_id in self.schemas else "")
                 for cid, ch in self.channels.items() if wanted is None or ch.topic in wanted}
        with open(self.path, "rb") as f:
            for index in self._chunk_indexes:
                if index.message_index_offsets and not names.keys() & index.message_index_offsets.keys():
                    continue  # no message of a wanted topic in this chunk
                f.seek(index.chunk_start_offset + 1 + 8)  # past the record's opcode and length
                stream, size = get_chunk_data_stream(Chunk.read(ReadDataStream(f)))
                buf = stream.read(size)
                pos = 0
                while pos < size:
                    opcode, length = _RECORD.unpack_from(buf, pos)
                    pos += _RECORD.size
                    if opcode == _MESSAGE_OPCODE:
                        channel, _sequence, log_time, publish_time = _MESSAGE.unpack_from(buf, pos)
                        name = names.get(channel)
                        if name is not None:
                            yield name[0], name[1], log_time, publish_time, buf[pos + _MESSAGE.size:pos + length]
                    pos += length

    def decoded(self, topics: list[str] | None = None) -> Iterator[tuple[RawMessage, Any]]:
        """(raw, decoded) pairs using mcap_ros2's dynamic decoder (no ROS needed)."""
        from mcap_ros2.decoder import DecoderFactory

        factory = DecoderFactory()
        decoders: dict[str, Callable[[bytes], Any]] = {}
        by_type = {s.name: s for s in self.schemas.values()}
        for raw in self.messages(topics):
            dec = decoders.get(raw.type_name)
            if dec is None:
                schema = by_type[raw.type_name]
                dec = factory.decoder_for("cdr", schema)
                if dec is None:  # mcap_ros2 decodes ros2msg schemas only
                    raise McapFileError(f"{self.path}: {raw.topic} [{raw.type_name}]: schema encoding "
                                        f"{schema.encoding!r} cannot be decoded here (ros2msg only)",
                                        path=self.path, kind="unsupported_schema")
                decoders[raw.type_name] = dec
            yield raw, dec(raw.data)


def bag_file_of(path: str | Path) -> BagFile | None:
    """The bag-metadata entry of a complete MCAP (from its summary: times, topics, counts); None if the file is
    missing, unreadable or cut (a cut file is not listed in a bag: ``mcap-recover`` rebuilds it first)."""
    try:
        reader = RunReader(path)
    except (McapFileError, OSError):
        return None
    if not reader.complete:
        return None
    topics = [TopicCount(t.topic, t.type_name, t.offered_qos_profiles,
                         reader.channels[cid].metadata.get("topic_type_hash", ""), t.message_count)
              for cid, t in zip(sorted(reader.channels), reader.topics(), strict=True)]
    return BagFile(Path(path).name, reader.start_ns, reader.end_ns, topics)


class RunFiles:
    """Every file of a run read as one recording (the RunReader interface): files in time order (by their
    last message), topics merged, messages file after file (each in log-time order).

    A file that is cut holds its messages in memory while the object lives (as a RunReader does); complete
    files are read through their indexes.
    """

    def __init__(self, path: str | Path, files: list[RunReader]):
        self.path = Path(path)
        self.files = sorted(files, key=lambda r: (r.end_ns, r.path.name))
        self.complete = all(r.complete for r in self.files)
        self.truncated = any(r.truncated for r in self.files)

    def check_complete(self) -> None:
        """McapFileError for the first file that was cut short."""
        for reader in self.files:
            reader.check_complete()

    def topics(self) -> list[TopicSummary]:
        """Every topic of every file, message counts summed (type, QoS and schema of its first file)."""
        merged: dict[str, TopicSummary] = {}
        for reader in self.files:
            for t in reader.topics():
                known = merged.get(t.topic)
                merged[t.topic] = t if known is None else TopicSummary(
                    t.topic, known.type_name, known.message_count + t.message_count, known.offered_qos_profiles,
                    known.schema_text)
        return list(merged.values())

    def message_count(self) -> int:
        """Messages in every file."""
        return sum(r.message_count() for r in self.files)

    def messages(self, topics: list[str] | None = None) -> Iterator[RawMessage]:
        """Raw messages, file after file."""
        for reader in self.files:
            yield from reader.messages(topics)

    def decoded(self, topics: list[str] | None = None) -> Iterator[tuple[RawMessage, Any]]:
        """(raw, decoded) pairs, file after file (each file with its own schemas)."""
        for reader in self.files:
            yield from reader.decoded(topics)


def open_run(path: str | Path, allow_truncated: bool = False, verify: bool = False) -> RunReader | RunFiles:
    """The recording at ``path``: a RunReader of its one file, RunFiles of a run folder's several files.

    Args:
        path: a .mcap or a run folder (bag directory; ``files.run_files``).
        allow_truncated: accept files cut short by a crash (their whole chunks are read).
        verify: check every file's CRCs and records first (``integrity.verify_mcap``).

    Raises:
        McapFileError: one clear line when a file cannot be used (missing, empty, not MCAP, truncated
            unless allowed, corrupted when verified).
    """
    paths = run_files(path)
    if verify:
        for p in paths:
            verify_mcap(p, allow_truncated=allow_truncated)
    readers = [RunReader(p) for p in paths]
    run: RunReader | RunFiles = readers[0] if len(readers) == 1 else RunFiles(path, readers)
    if not allow_truncated:
        run.check_complete()
    return run
