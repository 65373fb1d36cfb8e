"""Rebuild a complete, indexed rosbag2-layout MCAP from a file cut short (``stewart-vibration mcap-recover``).

The input is read record by record as far as records are whole (files.read_layout):
every complete chunk (CRC checked) and every top-level schema, channel,
message, metadata and attachment record is kept; of a chunk cut by the crash,
the messages that decompress whole are salvaged. The output is written fresh by
a BagFileWriter: profile ``ros2``, the recorded schemas (``ros2msg``) and
channel metadata (``offered_qos_profiles``, ``topic_type_hash``), ``cdr``
messages with their log/publish times and sequence numbers, zstd chunks with
chunk and message indexes, statistics, a ``rosbag2`` metadata record, and a
``metadata.yaml`` beside it so its folder opens as a bag directory.
"""

from __future__ import annotations

import io
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import cast

from mcap.data_stream import ReadDataStream
from mcap.records import Attachment, Channel, Chunk, Header, Message, Metadata, Schema

from .bag_metadata import bag_metadata, write_metadata_yaml
from .files import CHUNK, MAGIC, Layout, McapFileError, read_layout
from .integrity import decompress
from .writer import BagFileWriter

LIBRARY = "stewart_vibration mcap-recover (python mcap writer)"
_HEADER, _SCHEMA, _CHANNEL, _MESSAGE, _ATTACHMENT, _METADATA, _DATA_END = 0x01, 0x03, 0x04, 0x05, 0x09, 0x0C, 0x0F
_INNER_HEAD = struct.Struct("<BQ")
_CHUNK_FIXED = struct.Struct("<QQQI")  # start, end, uncompressed size, crc


@dataclass
class TopicRecovered:
    """One topic of the recovered file: its name, message type and messages recovered."""

    topic: str
    type_name: str
    messages: int = 0


@dataclass
class PartialChunk:
    """The chunk the crash cut: where, its time range, how many of its messages were salvaged."""

    offset: int
    start_ns: int
    end_ns: int
    compression: str
    bytes_present: int
    bytes_declared: int
    salvaged: int = 0


@dataclass
class RecoveryReport:
    """What ``recover`` read from the input and wrote to the output (times: log time, ns).

    ``output`` and ``metadata_yaml`` are None when not written; ``corrupt_chunks`` names the chunks
    skipped as damaged.
    """

    source: Path
    output: Path | None
    layout: Layout
    profile: str = ""
    library: str = ""
    topics: dict[str, TopicRecovered] = field(default_factory=dict)
    start_ns: int | None = None
    end_ns: int | None = None
    chunks_read: int = 0
    corrupt_chunks: list[str] = field(default_factory=list)
    partial_chunk: PartialChunk | None = None
    orphan_messages: int = 0  # messages whose channel or schema record was lost
    not_cdr_messages: int = 0  # messages of channels not in cdr encoding (a rosbag2 bag holds cdr only)
    attachments: int = 0
    metadata_yaml: Path | None = None

    @property
    def messages(self) -> int:
        """Messages recovered (written to the output, if any), over all topics."""
        return sum(t.messages for t in self.topics.values())

    @property
    def complete_input(self) -> bool:
        """True when the input had its footer (it was closed, not cut)."""
        return self.layout.footer

    @property
    def data_lost(self) -> bool:
        """True when part of the input was not recovered: cut, damaged chunks, orphaned or non-cdr messages."""
        return (not self.layout.footer or bool(self.corrupt_chunks) or self.orphan_messages > 0
                or self.not_cdr_messages > 0 or self.layout.bytes_unread > 0)

    def as_dict(self) -> dict:
        """The report as JSON-ready values (paths as strings, times in ns, sizes in bytes)."""
        p = self.partial_chunk
        return {
            "source": str(self.source),
            "output": str(self.output) if self.output else None,
            "metadata_yaml": str(self.metadata_yaml) if self.metadata_yaml else None,
            "input_complete": self.complete_input,
            "input_bytes": self.layout.size,
            "bytes_read": self.layout.good_end,
            "bytes_unread": self.layout.bytes_unread,
            "stop_reason": self.layout.stop_reason,
            "chunks_read": self.chunks_read,
            "corrupt_chunks": list(self.corrupt_chunks),
            "partial_chunk": None if p is None else {
                "offset": p.offset, "start_ns": p.start_ns, "end_ns": p.end_ns, "bytes_present": p.bytes_present,
                "bytes_declared": p.bytes_declared, "salvaged_messages": p.salvaged},
            "orphan_messages": self.orphan_messages,
            "not_cdr_messages": self.not_cdr_messages,
            "attachments": self.attachments,
            "messages": self.messages,
            "start_ns": self.start_ns,
            "end_ns": self.end_ns,
            "topics": {t.topic: {"type": t.type_name, "messages": t.messages} for t in self.topics.values()},
            "data_lost": self.data_lost,
        }


class _Rebuilder:
    """Turns recovered records into the output file (topics registered on first use)."""

    def __init__(self, report: RecoveryReport, out: Path | None, chunk_size: int):
        self.report = report
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self.writer = BagFileWriter(out, chunk_size=chunk_size, library=LIBRARY) if out else None
        self.in_summary = False

    def record(self, opcode: int, stream: ReadDataStream, length: int) -> None:
        if opcode == _SCHEMA:
            s = Schema.read(stream)
            self.schemas.setdefault(s.id, s)
        elif opcode == _CHANNEL:
            c = Channel.read(stream)
            self.channels.setdefault(c.id, c)
        elif opcode == _MESSAGE:
            self.message(Message.read(stream, length))
        elif self.in_summary:
            return
        elif opcode == _HEADER:
            h = Header.read(stream)
            self.report.profile, self.report.library = h.profile, h.library
        elif opcode == _METADATA:
            m = Metadata.read(stream)
            if m.name != "rosbag2" and self.writer is not None:  # rosbag2's is rewritten at the end
                self.writer.add_metadata(m.name, dict(m.metadata))
        elif opcode == _ATTACHMENT:
            a = Attachment.read(stream)
            self.report.attachments += 1
            if self.writer is not None:
                self.writer.add_attachment(a)
        elif opcode == _DATA_END:
            self.in_summary = True

    def message(self, msg: Message) -> None:
        ch = self.channels.get(msg.channel_id)
        schema = self.schemas.get(ch.schema_id) if ch is not None else None
        if ch is None or schema is None:
            self.report.orphan_messages += 1
            return
        if ch.message_encoding != "cdr":
            self.report.not_cdr_messages += 1
            return
        info = self.report.topics.get(ch.topic)
        if info is None:
            info = self.report.topics[ch.topic] = TopicRecovered(ch.topic, schema.name)
            if self.writer is not None:
                self.writer.add_topic(
                    ch.topic, schema.name, ch.metadata.get("offered_qos_profiles", ""),
                    ch.metadata.get("topic_type_hash", ""), schema_text=schema.data.decode("utf-8", "replace"),
                    schema_encoding=schema.encoding or "ros2msg")
        elif info.type_name != schema.name:  # the same topic with another type: not representable in a bag
            self.report.orphan_messages += 1
            return
        info.messages += 1
        r = self.report
        r.start_ns = msg.log_time if r.start_ns is None else min(r.start_ns, msg.log_time)
        r.end_ns = msg.log_time if r.end_ns is None else max(r.end_ns, msg.log_time)
        if self.writer is not None:
            self.writer.write(ch.topic, msg.log_time, msg.data, msg.publish_time, msg.sequence)

    def inner_records(self, data: bytes, whole: bool) -> int:
        """Records of an uncompressed chunk body; stops quietly at a cut record unless ``whole``."""
        stream = ReadDataStream(io.BytesIO(data))
        pos, n, count = 0, len(data), 0
        while pos + _INNER_HEAD.size <= n:
            opcode, length = _INNER_HEAD.unpack_from(data, pos)
            if pos + _INNER_HEAD.size + length > n:
                break
            stream.read(_INNER_HEAD.size)
            before = self.report.messages
            self.record(opcode, stream, length)
            count += self.report.messages - before
            pos += _INNER_HEAD.size + length
            consumed = stream.count
            if consumed < pos:  # skip what a record reader left (unknown opcodes, padding)
                stream.read(pos - consumed)
        if whole and pos != n:
            raise ValueError(f"chunk body has {n - pos} bytes after its last record")
        return count


def _decompress_prefix(compression: str, data: bytes) -> bytes:
    """As much of a cut compressed stream as decodes."""
    try:
        if compression == "zstd":
            import zstandard

            return zstandard.ZstdDecompressor().decompressobj().decompress(data)
        if compression == "lz4":
            import lz4.frame

            return lz4.frame.LZ4FrameDecompressor().decompress(data)
        if compression == "":
            return data
    except Exception:  # noqa: BLE001 - the tail is damaged: salvage nothing from it
        return b""
    return b""


def _chunk(rebuilder: _Rebuilder, raw: bytes, offset: int) -> None:
    chunk = Chunk.read(ReadDataStream(io.BytesIO(raw)))
    data = decompress(chunk.compression, chunk.data, chunk.uncompressed_size)
    if len(data) != chunk.uncompressed_size:
        raise ValueError(f"decompressed to {len(data)} bytes, expected {chunk.uncompressed_size}")
    if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
        raise ValueError("CRC mismatch")
    rebuilder.inner_records(data, whole=True)


def _partial_chunk(rebuilder: _Rebuilder, raw: bytes, offset: int, declared: int) -> PartialChunk | None:
    if len(raw) < _CHUNK_FIXED.size + 4:
        return None
    start, end, _size, _crc = _CHUNK_FIXED.unpack_from(raw, 0)
    (clen,) = struct.unpack_from("<I", raw, _CHUNK_FIXED.size)
    body = _CHUNK_FIXED.size + 4 + clen + 8
    compression = raw[_CHUNK_FIXED.size + 4 : _CHUNK_FIXED.size + 4 + clen].decode("utf-8", "replace")
    info = PartialChunk(offset, start, end, compression, len(raw), declared)
    if len(raw) > body:
        info.salvaged = rebuilder.inner_records(_decompress_prefix(compression, raw[body:]), whole=False)
    return info


def recover(src: str | Path, out: str | Path | None, chunk_size: int = 256 * 1024,
            write_metadata: bool = True) -> RecoveryReport:
    """Rebuild ``src`` into ``out`` (None: only analyse) and, with ``write_metadata``, write
    ``metadata.yaml`` beside ``out``. McapFileError if ``src`` is unusable or holds no whole message
    (then no output is left behind)."""
    src = Path(src)
    layout = read_layout(src)
    out_path = Path(out) if out is not None else None
    if out_path is not None and out_path.resolve() == src.resolve():
        raise McapFileError(f"{src}: the output must be another file than the input", path=src, kind="bad_bag")
    report = RecoveryReport(src, out_path, layout)
    rebuilder = _Rebuilder(report, out_path, chunk_size)
    try:
        _walk(rebuilder, src, layout)
        if report.messages == 0:
            what = (f"its {report.not_cdr_messages} messages are not cdr-encoded (a rosbag2 bag holds cdr only)"
                    if report.not_cdr_messages else
                    f"no complete message in the {layout.good_end:,} readable of {layout.size:,} bytes"
                    + (f" ({layout.stop_reason})" if layout.stop_reason else ""))
            raise McapFileError(
                f"{src}: nothing to recover: {what}",
                path=src, kind="truncated" if not layout.footer else "empty", bytes_read=layout.good_end,
                size=layout.size)
        bag_file = rebuilder.writer.finish() if rebuilder.writer is not None else None
    except BaseException:
        if out_path is not None:
            if rebuilder.writer is not None:
                rebuilder.writer.abort()
            out_path.unlink(missing_ok=True)
        raise
    if write_metadata and bag_file is not None:
        # a bag file comes only from a writer, which exists only with an output path
        report.metadata_yaml = write_metadata_yaml(cast(Path, out_path).parent, bag_metadata([bag_file]))
    return report


def _walk(rebuilder: _Rebuilder, src: Path, layout: Layout) -> None:
    report = rebuilder.report
    with open(src, "rb") as f:
        for opcode, start, length in layout.records:
            f.seek(start)
            raw = f.read(length)
            if opcode == CHUNK:
                try:
                    _chunk(rebuilder, raw, start)
                    report.chunks_read += 1
                except Exception as exc:  # noqa: BLE001 - a damaged chunk is skipped and reported
                    report.corrupt_chunks.append(f"chunk at offset {start - 9:,}: {exc}")
                continue
            try:
                rebuilder.record(opcode, ReadDataStream(io.BytesIO(raw)), length)
            except Exception as exc:  # noqa: BLE001 - a damaged record is skipped and reported
                report.corrupt_chunks.append(f"record 0x{opcode:02x} at offset {start - 9:,}: {exc}")
        if layout.partial is not None and layout.partial[0] == CHUNK:
            opcode, start, declared = layout.partial
            f.seek(start)
            report.partial_chunk = _partial_chunk(rebuilder, f.read(), start - 9, declared)


__all__ = ["MAGIC", "McapFileError", "PartialChunk", "RecoveryReport", "TopicRecovered", "recover"]
