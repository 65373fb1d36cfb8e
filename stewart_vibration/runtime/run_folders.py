"""Where runs are written (pure filesystem): one folder per run, ``runs/latest`` pointing at the newest.

``new_run_folder(runs)`` creates ``runs/run_<YYYYmmdd_HHMMSS>`` (``_2``, ``_3`` ... if taken) and points the
relative symlink ``runs/latest`` at it (replaced atomically), so every run keeps its own bag directory (one
``.mcap`` + ``metadata.yaml``, ``logs/``, ``report/``, ``summary.json``) and ``runs/latest`` is always the
newest. A real ``runs/latest`` directory left by an older version is moved aside to ``runs/run_<its mtime>``,
never deleted.
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
