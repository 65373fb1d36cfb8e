"""The report's figures drawn by worker processes are the figures drawn one after the other in this process."""

from __future__ import annotations

import pytest
from test_mcap_report import _write_run

from stewart_vibration.analysis import plot_pool
from stewart_vibration.analysis.report_data import report_data
from stewart_vibration.analysis.run_report import _events, summarize
from stewart_vibration.kinematics.robot_config import load_robot
from stewart_vibration.mcap_log.reader import open_run


def test_workers_write_the_same_figures_as_one_process(tmp_path, monkeypatch):
    path = tmp_path / "run.mcap"
    _write_run(path, n=2_000)
    robot = load_robot()
    reader = open_run(path, verify=True)
    data, signals = report_data(reader, robot)
    data["events"] = _events(reader, data["time_origin_ns"])
    summary = summarize(reader, data, signals, robot)
    written = {}
    for workers in (2, 1):
        out = tmp_path / f"workers_{workers}"
        out.mkdir()
        monkeypatch.setattr(plot_pool, "worker_count", lambda: 2)  # two workers even on a one-core machine
        with plot_pool.PlotPool(workers) as pool:
            assert (pool._pool is not None) == (workers == 2)
            pool.start(data, out)
            written[workers] = pool.finish(summary)
    assert written[2] == written[1] == ["leg_lengths.png", "vibration.png", "platform.png", "forces.png",
                                        "forces_vibration.png", "events.png"]
    for name in written[2]:
        assert (tmp_path / "workers_2" / name).read_bytes() == (tmp_path / "workers_1" / name).read_bytes()


def test_finish_needs_start():
    with plot_pool.PlotPool(1) as pool, pytest.raises(RuntimeError):
        pool.finish({})
