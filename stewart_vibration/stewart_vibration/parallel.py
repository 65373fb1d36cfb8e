"""Split a large batch over the CPU cores with threads.

numpy ufuncs and BLAS release the GIL, so contiguous row ranges of a batch
run truly in parallel in a thread pool. Each worker thread limits OpenBLAS to
one thread for itself (``openblas_set_num_threads_local``, OpenBLAS >= 0.3.27)
so the workers do not fight over BLAS threads; other threads are untouched.

Worker count: the CPUs this process may run on, or the environment variable
STEWART_VIBRATION_THREADS (1 disables threading). Small batches always run in
the calling thread.
"""

from __future__ import annotations

import ctypes
import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

T = TypeVar("T")

_lock = threading.Lock()
_pool: ThreadPoolExecutor | None = None


def worker_count() -> int:
    """Threads used for large batches (>= 1)."""
    configured = os.environ.get("STEWART_VIBRATION_THREADS", "").strip()
    if configured:
        try:
            return max(1, int(configured))
        except ValueError:
            return 1
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def _openblas_local_setter() -> Callable[[int], int] | None:
    """openblas_set_num_threads_local of the OpenBLAS loaded in this process, or None."""
    try:
        with open("/proc/self/maps") as maps:
            paths = {line.split()[-1] for line in maps if "openblas" in line.lower() and ".so" in line}
    except OSError:
        return None
    for path in sorted(paths):
        try:
            setter = ctypes.CDLL(path).openblas_set_num_threads_local
        except (OSError, AttributeError):
            continue
        setter.argtypes, setter.restype = [ctypes.c_int], ctypes.c_int
        return setter
    return None


def _single_blas_thread() -> None:
    setter = _openblas_local_setter()
    if setter is not None:
        setter(1)


def _executor(workers: int) -> ThreadPoolExecutor:
    global _pool
    with _lock:
        if _pool is None or _pool._max_workers != workers:  # noqa: SLF001 - resize on a changed setting
            if _pool is not None:
                _pool.shutdown(wait=False)
            _pool = ThreadPoolExecutor(workers, thread_name_prefix="stewart-batch", initializer=_single_blas_thread)
        return _pool


def row_ranges(count: int, parts: int, align: int = 1) -> list[tuple[int, int]]:
    """Split rows [0, count) into at most ``parts`` contiguous (start, stop) ranges,
    every boundary a multiple of ``align``, none empty."""
    if count <= 0:
        return []
    blocks = -(-count // align)
    parts = max(1, min(parts, blocks))
    bounds = [min(count, (blocks * k // parts) * align) for k in range(parts + 1)]
    return [(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


def map_row_ranges(
    work: Callable[[int, int], T], count: int, *, min_rows: int = 65_536, align: int = 1
) -> list[T]:
    """[work(start, stop) for each range] over the worker threads, in row order.

    Runs ``work(0, count)`` in the calling thread when the batch is smaller
    than ``min_rows`` or only one worker is configured. ``work`` must write
    only its own rows. The first exception raised by a range is re-raised.
    """
    workers = worker_count()
    if count < min_rows or workers == 1:
        return [work(0, count)]
    ranges = row_ranges(count, workers, align)
    futures = [_executor(workers).submit(work, start, stop) for start, stop in ranges]
    return [future.result() for future in futures]
