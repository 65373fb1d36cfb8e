"""Where runs are written (pure filesystem): one folder per run, ``runs/latest`` pointing at the newest.

``new_run_folder(runs)`` creates ``runs/run_<YYYYmmdd_HHMMSS>`` (``_2``, ``_3`` ... if taken) and points the
relative symlink ``runs/latest`` at it (replaced atomically), so every run keeps its own bag directory (one
``.mcap`` + ``metadata.yaml``, ``logs/``, ``report/``, ``summary.json``) and ``runs/latest`` is always the
newest. A real ``runs/latest`` directory left by an older version is moved aside to ``runs/run_<its mtime>``,
never deleted.

``reserve_file`` / ``write_reserved``: the run's summary gets its disk space when the run starts, so a run that
fills the disk (the recording stops there) can still write what it recorded.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

LATEST = "latest"


def _unique(runs: Path, stamp: str) -> Path:
    candidate, n = runs / f"run_{stamp}", 2
    while candidate.exists() or candidate.is_symlink():
        candidate, n = runs / f"run_{stamp}_{n}", n + 1
    return candidate


def new_run_folder(runs: str | os.PathLike, now: float | None = None) -> Path:
    """Create a new run folder under ``runs`` and point ``runs/latest`` at it; returns the folder."""
    runs = Path(runs)
    runs.mkdir(parents=True, exist_ok=True)
    latest = runs / LATEST
    if latest.is_dir() and not latest.is_symlink():  # an older version's single run folder: keep it
        old = time.strftime("%Y%m%d_%H%M%S", time.localtime(latest.stat().st_mtime))
        latest.rename(_unique(runs, old))
    folder = _unique(runs, time.strftime("%Y%m%d_%H%M%S", time.localtime(now)))
    folder.mkdir()
    temporary = runs / f".{LATEST}.{os.getpid()}"
    if temporary.is_symlink() or temporary.exists():
        temporary.unlink()
    temporary.symlink_to(folder.name)
    os.replace(temporary, latest)
    return folder


def reserve_file(path: str | os.PathLike, size_bytes: int) -> Path:
    """Allocate ``size_bytes`` on disk for a file written at the end (the hidden ``.<name>.reserve`` beside
    ``path``); returns the reserve's path. An OSError (the disk is already full) leaves no reserve."""
    path = Path(path)
    reserve = path.with_name(f".{path.name}.reserve")
    fd = os.open(reserve, os.O_WRONLY | os.O_CREAT, 0o644)
    try:
        os.posix_fallocate(fd, 0, int(size_bytes))
    except OSError:
        os.close(fd)
        reserve.unlink(missing_ok=True)
        raise
    os.close(fd)
    return reserve


def write_reserved(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` to ``path``: into the space ``reserve_file`` allocated for it when there is one (no new
    blocks needed, so it works on a full disk while it fits), else as a new file; returns ``path``.

    Raises:
        OSError: the text does not fit and the disk has no room for it.
    """
    path = Path(path)
    reserve = path.with_name(f".{path.name}.reserve")
    data = text.encode()
    if not reserve.exists() or reserve.stat().st_size < len(data):
        path.write_bytes(data)
        reserve.unlink(missing_ok=True)
        return path
    fd = os.open(reserve, os.O_WRONLY)
    try:
        view = memoryview(data)
        offset = 0
        while offset < len(data):
            offset += os.pwrite(fd, view[offset:], offset)
        os.ftruncate(fd, len(data))
    finally:
        os.close(fd)
    os.replace(reserve, path)
    return path
