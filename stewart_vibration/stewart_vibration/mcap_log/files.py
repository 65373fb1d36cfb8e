"""Find and check MCAP inputs: bag directories, missing / empty / foreign / truncated files.

Every problem is a ``McapFileError`` (a StewartError, so the CLI prints it as
one line and exits 2) whose message says which file and what is wrong; a
truncated file says how much of it is whole records.

``read_layout`` walks the top-level records of a file by their length fields
(no decompression): where the whole records end, whether the footer is there,
and the record cut short by a crash, if any.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from pathlib import Path, PurePath

from ..errors import StewartError
from .bag_metadata import METADATA_FILE, read_metadata_yaml

MAGIC = b"\x89MCAP0\r\n"
RECORD_NAMES = {
    0x01: "Header", 0x02: "Footer", 0x03: "Schema", 0x04: "Channel", 0x05: "Message", 0x06: "Chunk",
    0x07: "MessageIndex", 0x08: "ChunkIndex", 0x09: "Attachment", 0x0A: "AttachmentIndex",
    0x0B: "Statistics", 0x0C: "Metadata", 0x0D: "MetadataIndex", 0x0E: "SummaryOffset", 0x0F: "DataEnd",
}
FOOTER, CHUNK = 0x02, 0x06
_RECORD_HEAD = struct.Struct("<BQ")


class McapFileError(StewartError, ValueError):
    """An MCAP input that cannot be used as asked; ``kind``: missing, unreadable, empty, not_mcap,
    truncated, bad_bag, unsupported_schema. ``bytes_read`` / ``size``: for truncated files, the whole-record prefix."""

    def __init__(self, message: str, *, path, kind: str, bytes_read: int | None = None, size: int | None = None):
        super().__init__(message)
        self.path = Path(path)
        self.kind = kind
        self.bytes_read = bytes_read
        self.size = size


@dataclass
class Layout:
    """Top-level records of an MCAP file, as far as they are whole."""

    size: int
    good_end: int = len(MAGIC)  # end offset of the last whole record
    records: list[tuple[int, int, int]] = field(default_factory=list)  # (opcode, content offset, length)
    footer: bool = False  # footer and closing magic present
    stop_reason: str | None = None  # why the walk ended before a footer
    partial: tuple[int, int, int] | None = None  # (opcode, content offset, declared length) of a cut record

    @property
    def chunks(self) -> int:
        """Number of whole Chunk records."""
        return sum(1 for r in self.records if r[0] == CHUNK)

    @property
    def bytes_unread(self) -> int:
        """Bytes after the last whole record (a cut record and anything after it)."""
        return self.size - self.good_end


def _fmt_bytes(n: int) -> str:
    return f"{n:,} bytes"


def check_readable(path: str | Path) -> int:
    """Size of an existing, readable, non-empty file that starts with the MCAP magic; else McapFileError."""
    p = Path(path)
    if not p.exists():
        raise McapFileError(f"{p}: no such file", path=p, kind="missing")
    if not p.is_file():
        raise McapFileError(f"{p}: not a regular file", path=p, kind="unreadable")
    try:
        with open(p, "rb") as f:
            head = f.read(len(MAGIC))
    except OSError as exc:
        raise McapFileError(f"{p}: cannot be read ({exc.strerror or exc})", path=p, kind="unreadable") from None
    size = p.stat().st_size
    if size == 0:
        raise McapFileError(f"{p}: empty file (0 bytes), not an MCAP recording", path=p, kind="empty", size=0)
    if head != MAGIC[: len(head)] or len(head) < len(MAGIC):
        what = "too short" if head == MAGIC[: len(head)] else f"starts with {head[:8].hex(' ')}"
        raise McapFileError(
            f"{p}: not an MCAP file ({_fmt_bytes(size)}, {what}; an MCAP starts with 89 4d 43 41 50 30 0d 0a)",
            path=p, kind="not_mcap", size=size,
        )
    return size


def read_layout(path: str | Path) -> Layout:
    """Walk the top-level records (seeking over their contents); the file must pass check_readable."""
    size = check_readable(path)
    layout = Layout(size=size)
    with open(path, "rb") as f:
        pos = len(MAGIC)
        f.seek(pos)
        while True:
            if pos == size:
                layout.stop_reason = f"the file ends after {_fmt_bytes(size)} without a footer"
                break
            if size - pos < _RECORD_HEAD.size:
                layout.stop_reason = f"cut inside a record header at offset {pos:,}"
                break
            opcode, length = _RECORD_HEAD.unpack(f.read(_RECORD_HEAD.size))
            name = RECORD_NAMES.get(opcode)
            if name is None and opcode < 0x80:
                layout.stop_reason = f"unreadable data at offset {pos:,} (invalid record opcode 0x{opcode:02x})"
                break
            start = pos + _RECORD_HEAD.size
            if start + length > size:
                layout.partial = (opcode, start, length)
                layout.stop_reason = (
                    f"cut inside a {name or 'private'} record at offset {pos:,} "
                    f"({_fmt_bytes(size - start)} of its {_fmt_bytes(length)} present)"
                )
                break
            layout.records.append((opcode, start, length))
            pos = start + length
            f.seek(pos)
            layout.good_end = pos
            if opcode == FOOTER:
                if f.read(len(MAGIC)) == MAGIC:
                    layout.footer = True
                    layout.good_end = pos + len(MAGIC)
                else:
                    layout.stop_reason = "the footer is not followed by the closing magic"
                break
    return layout


def truncated_error(path: str | Path, layout: Layout | None = None) -> McapFileError:
    """The McapFileError for a file without a whole footer/summary: how much is whole records."""
    layout = layout or read_layout(path)
    return McapFileError(
        f"{path}: truncated MCAP ({layout.stop_reason}); {_fmt_bytes(layout.good_end)} of "
        f"{_fmt_bytes(layout.size)} read as whole records ({layout.chunks} complete chunks). "
        f"Rebuild it with: stewart-vibration mcap-recover {path}",
        path=path, kind="truncated", bytes_read=layout.good_end, size=layout.size,
    )


RECOVERED_SUFFIX = ".recovered.mcap"  # mcap-recover's default output beside a cut file


def run_files(path: str | Path) -> list[Path]:
    """Every recording of a run: ``path`` itself for a file; for a folder every ``.mcap`` in it (a recorder
    that restarted leaves one file per start, and its cut files are not listed in metadata.yaml), a cut file
    replaced by its ``.recovered.mcap`` when that exists. Sorted by name; ``RunFiles`` orders them in time.

    Raises:
        McapFileError: missing; a folder without any .mcap; a metadata.yaml that lists a missing file.
    """
    p = Path(path)
    if not p.exists():
        raise McapFileError(f"{p}: no such file or directory", path=p, kind="missing")
    if not p.is_dir():
        return [p]
    meta_path = p / METADATA_FILE
    if meta_path.is_file():
        try:
            listed = [PurePath(str(x)).name for x in read_metadata_yaml(p)["relative_file_paths"]]
        except Exception as exc:  # noqa: BLE001 - any malformed metadata: one clear line
            raise McapFileError(f"{meta_path}: not a valid rosbag2 metadata file ({exc})", path=meta_path,
                                kind="bad_bag") from None
        for name in listed:
            if not (p / name).is_file():
                raise McapFileError(f"{p}: {METADATA_FILE} lists {name}, which is missing", path=p / name,
                                    kind="missing")
    mcaps = sorted(m for m in p.glob("*.mcap") if m.is_file())
    names = {m.name for m in mcaps}
    mcaps = [m for m in mcaps if m.name.removesuffix(".mcap") + RECOVERED_SUFFIX not in names]
    if not mcaps:
        raise McapFileError(f"{p}: a directory with neither {METADATA_FILE} nor a .mcap file", path=p,
                            kind="missing")
    return mcaps
