"""Shared by the benchmarks that repeat a run beside busy CPU hogs (load.py, suite_under_load.py)."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager

HOG = "while True: pass"


@contextmanager
def cpu_hogs(count: int) -> Iterator[list[subprocess.Popen]]:
    """Keep ``count`` processes spinning at normal priority while the block runs; kill them after it."""
    procs = [subprocess.Popen([sys.executable, "-c", HOG]) for _ in range(count)]
    try:
        yield procs
    finally:
        for proc in procs:
            proc.kill()
            proc.wait()


def summarise(rows: list[dict], ok_key: str, hogs: int, as_json: bool, sentence: str) -> int:
    """Print the verdict over ``rows`` (JSON or ``"N of M runs <sentence> with K CPU hog(s)..."``); the exit
    code: 0 only when every row's ``ok_key`` is true."""
    good = sum(bool(row[ok_key]) for row in rows)
    if as_json:
        print(json.dumps({"hogs": hogs, "runs": rows, ok_key: good}, indent=2))
    else:
        print(f"{good} of {len(rows)} runs {sentence} with {hogs} CPU hog(s) beside the suite")
    return 0 if good == len(rows) else 1
