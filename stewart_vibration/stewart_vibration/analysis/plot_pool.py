"""The report's figures drawn in worker processes, one figure a task (``run_plots.FIGURES``).

Drawing a figure is matplotlib's Python work, a few tenths of a second each, one after the other in one process; on
two cores two workers halve it. The workers are forked as the report starts and import matplotlib while the report
reads the run, so the import costs the report nothing either; the figures drawn from the data alone start while the
summary is computed. Without fork, or with one core (``parallel.worker_count``: the cores this process may run on, or
STEWART_VIBRATION_THREADS), the figures are drawn here, one after the other.
"""

from __future__ import annotations

import multiprocessing
from concurrent.futures import Future, ProcessPoolExecutor
from pathlib import Path

from ..parallel import worker_count

WORKERS = 2  # more processes than cores only compete for them: the report runs on two


def _import_plots() -> None:
    """A worker's start: matplotlib imported before its first figure is asked for."""
    from . import run_plots  # noqa: F401


def _figures() -> tuple[int, set[int]]:
    """(how many figures ``run_plots.FIGURES`` holds, the indices of those that read the summary): asked of a
    worker, which imports matplotlib to answer (this process need not)."""
    from . import run_plots

    return len(run_plots.FIGURES), {run_plots.FIGURES.index(f) for f in run_plots.TITLED}


def _draw(index: int, data: dict, summary: dict | None, out: Path) -> list[str]:
    """A worker's task: figure ``index`` of ``run_plots.FIGURES``; returns the names it wrote."""
    from . import run_plots

    return run_plots.FIGURES[index](data, summary or {}, out)


class PlotPool:
    """Workers that draw the report's figures: ``start`` with the run's data, ``finish`` with its summary. Use as
    a context manager (the workers end with it)."""

    def __init__(self, workers: int = WORKERS):
        workers = min(workers, worker_count())
        self._pool: ProcessPoolExecutor | None = None
        self._tasks: dict[int, Future] = {}
        self._data: tuple[dict, Path] | None = None
        if workers > 1 and "fork" in multiprocessing.get_all_start_methods():
            self._pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork"),
                                             initializer=_import_plots)
            self._figures = self._pool.submit(_figures)  # the workers start (each importing matplotlib) now

    def __enter__(self) -> PlotPool:
        return self

    def __exit__(self, *exc) -> None:
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)

    def start(self, data: dict, out: Path) -> None:
        """Begin the figures drawn from the run's data alone (``report_data.report_data``), into ``out``."""
        self._data = data, out
        if self._pool is not None:
            count, titled = self._figures.result()
            self._tasks = {i: self._pool.submit(_draw, i, data, None, out) for i in range(count) if i not in titled}

    def finish(self, summary: dict) -> list[str]:
        """The rest of the figures, with the run's summary (``run_report.summarize``); returns the file names of
        every figure written, in ``run_plots.FIGURES``' order. A figure's exception is raised here."""
        if self._data is None:
            raise RuntimeError("PlotPool.finish before start")
        data, out = self._data
        if self._pool is None:
            from . import run_plots

            return run_plots.plot_all(data, summary, out)
        count, titled = self._figures.result()
        self._tasks.update({i: self._pool.submit(_draw, i, data, summary, out) for i in sorted(titled)})
        return [name for i in range(count) for name in self._tasks[i].result()]
