"""Check an MCAP file's checksums and record structure before anything reads it (no rclpy).

``verify_mcap`` walks the file's whole top-level records (``files.read_layout``, no seeking through the
summary) and checks what the MCAP format lets a reader check:

- every Chunk: its compressed data decodes to exactly ``uncompressed_size`` bytes, whose CRC-32 is the
  chunk's ``uncompressed_crc`` (when the writer stored one), and whose records are whole;
- the DataEnd record: ``data_section_crc`` (when stored) is the CRC-32 of every byte before it;
- the Footer: ``summary_crc`` (when stored) is the CRC-32 of the summary section and the footer's
  first fields; ``summary_start`` points at a record after the data section;
- the record opcodes and lengths themselves (a length that runs past the file is a cut, reported by
  ``files.truncated_error``; an unknown opcode below 0x80 is damage).

A damaged file is one ``McapFileError`` (kind ``corrupt``) naming the file, the record and its offset.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

from .files import CHUNK, FOOTER, MAGIC, Layout, McapFileError, read_layout, truncated_error

DATA_END = 0x0F
_CHUNK_FIXED = struct.Struct("<QQQI")  # message start, end, uncompressed size, crc
_INNER_HEAD = struct.Struct("<BQ")
_FOOTER = struct.Struct("<QQI")  # summary start, summary offset start, summary crc
_RECORD_HEAD = 9  # opcode (1) + length (8)


def decompress(compression: str, data: bytes, size: int) -> bytes:
    """A chunk's records from its ``compression`` ("zstd", "lz4" or "") of at most ``size`` bytes."""
    if compression == "zstd":
        import zstandard

        return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
    if compression == "lz4":
        import lz4.frame

        return lz4.frame.decompress(data)
    if compression == "":
        return data
    raise ValueError(f"unsupported chunk compression {compression!r}")


def chunk_records(raw: bytes) -> bytes:
    """The uncompressed records of a Chunk record's content ``raw``, checked (ValueError says what is wrong)."""
    if len(raw) < _CHUNK_FIXED.size + 4:
        raise ValueError("chunk record too short for its header")
    _start, _end, size, crc = _CHUNK_FIXED.unpack_from(raw, 0)
    (name_len,) = struct.unpack_from("<I", raw, _CHUNK_FIXED.size)
    at = _CHUNK_FIXED.size + 4
    if at + name_len + 8 > len(raw):
        raise ValueError("chunk compression name or data length runs past the record")
    compression = raw[at:at + name_len].decode("utf-8", "replace")
    at += name_len
    (data_len,) = struct.unpack_from("<Q", raw, at)
    at += 8
    if at + data_len != len(raw):
        raise ValueError(f"chunk data length {data_len:,} does not match its record ({len(raw) - at:,} bytes)")
    try:
        data = decompress(compression, raw[at:], size)
    except Exception as exc:  # noqa: BLE001 - any codec error is damage, said in one line
        raise ValueError(f"its {compression or 'uncompressed'} data does not decode ({type(exc).__name__}: "
                         f"{exc})") from None
    if len(data) != size:
        raise ValueError(f"it decodes to {len(data):,} bytes, not the {size:,} it declares")
    if crc and zlib.crc32(data) != crc:
        raise ValueError(f"CRC mismatch (stored 0x{crc:08x}, computed 0x{zlib.crc32(data):08x})")
    pos = 0
    while pos < len(data):
        if pos + _INNER_HEAD.size > len(data):
            raise ValueError(f"a record header is cut at byte {pos:,} of its records")
        opcode, length = _INNER_HEAD.unpack_from(data, pos)
        if opcode in (0x00, CHUNK, FOOTER) or pos + _INNER_HEAD.size + length > len(data):
            raise ValueError(f"an invalid record (opcode 0x{opcode:02x}, {length:,} bytes) at byte {pos:,} of its "
                             "records")
        pos += _INNER_HEAD.size + length
    return data


def verify_mcap(path: str | Path, allow_truncated: bool = False) -> Layout:
    """Check every checksum and record of ``path``; returns its layout.

    Args:
        path: an MCAP file.
        allow_truncated: accept a file cut short (a crash): its whole records are checked.

    Returns:
        The file's ``Layout``.

    Raises:
        McapFileError: missing, empty or not MCAP (``files.check_readable``); truncated (unless
            ``allow_truncated``); ``corrupt``: a chunk, the data section or the summary fails its check.
    """
    layout = read_layout(path)
    if layout.stop_reason is not None and "invalid record opcode" in layout.stop_reason:
        raise _corrupt(path, layout.stop_reason)
    if not layout.footer and not allow_truncated:
        raise truncated_error(path, layout)
    with open(path, "rb") as f:
        crc = zlib.crc32(f.read(len(MAGIC)))  # the data section's CRC covers the leading magic too
        data_section = True
        summary_start = None
        for opcode, start, length in layout.records:
            head = start - _RECORD_HEAD
            f.seek(head)
            raw = f.read(_RECORD_HEAD + length)
            content = raw[_RECORD_HEAD:]
            if opcode == CHUNK:
                try:
                    chunk_records(content)
                except ValueError as exc:
                    raise _corrupt(path, f"chunk at offset {head:,}: {exc}") from None
            elif opcode == DATA_END and data_section:
                (stored,) = struct.unpack_from("<I", content, 0) if len(content) >= 4 else (0,)
                if stored and stored != crc:
                    raise _corrupt(path, f"data section CRC mismatch (stored 0x{stored:08x}, computed 0x{crc:08x})")
                data_section, summary_start = False, start + length
            elif opcode == FOOTER:
                _check_footer(path, f, content, head, summary_start)
            if data_section:
                crc = zlib.crc32(raw, crc)
    return layout


def _check_footer(path, f, content: bytes, head: int, data_end: int | None) -> None:
    if len(content) < _FOOTER.size:
        raise _corrupt(path, f"footer at offset {head:,} is {len(content)} bytes, not {_FOOTER.size}")
    summary_start, offset_start, stored = _FOOTER.unpack_from(content, 0)
    if summary_start and (summary_start >= head or (data_end is not None and summary_start < data_end)):
        raise _corrupt(path, f"footer points its summary at offset {summary_start:,}, outside the summary section")
    if not stored:
        return
    start = summary_start or head
    f.seek(start)
    summary = f.read(head - start)
    crc = zlib.crc32(struct.pack("<BQQQ", FOOTER, _FOOTER.size, summary_start, offset_start), zlib.crc32(summary))
    if crc != stored:
        raise _corrupt(path, f"summary CRC mismatch (stored 0x{stored:08x}, computed 0x{crc:08x})")


def _corrupt(path, what: str) -> McapFileError:
    return McapFileError(f"{path}: corrupted MCAP: {what}; its data cannot be trusted "
                         f"(stewart-vibration mcap-recover {path} keeps the chunks that pass)", path=path,
                         kind="corrupt")
