"""Test scaffolding: a small, size-limited filesystem to fill (a full disk, as a user's would be).

``small_filesystem(path, size_bytes)`` mounts a tmpfs of that size at ``path`` (root only); where tmpfs
cannot be mounted it makes a loop-mounted ext2 image of that size; where neither works it skips the test
with the reason. It unmounts on exit.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
from pathlib import Path

import pytest


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(list(args), capture_output=True, text=True, timeout=30)


@contextlib.contextmanager
def small_filesystem(path: Path, size_bytes: int):
    """A filesystem of ``size_bytes`` mounted at ``path`` (created), unmounted afterwards."""
    path.mkdir(parents=True, exist_ok=True)
    if os.geteuid() != 0:
        pytest.skip("a size-limited filesystem needs root (mount)")
    tried = []
    out = _run("mount", "-t", "tmpfs", "-o", f"size={size_bytes}", "tmpfs", str(path))
    if out.returncode != 0:
        tried.append(f"tmpfs: {out.stderr.strip()}")
        image = path.parent / f"{path.name}.img"
        if shutil.which("mkfs.ext2") is None:
            pytest.skip(f"no small filesystem can be made here ({'; '.join(tried)}; no mkfs.ext2)")
        with open(image, "wb") as f:
            f.truncate(size_bytes)
        made = _run("mkfs.ext2", "-q", "-F", "-m", "0", str(image))
        out = _run("mount", "-o", "loop", str(image), str(path)) if made.returncode == 0 else made
        if out.returncode != 0:
            tried.append(f"loop ext2: {out.stderr.strip()}")
            pytest.skip(f"no small filesystem can be made here ({'; '.join(tried)})")
    try:
        yield path
    finally:
        _run("umount", "-l", str(path))
