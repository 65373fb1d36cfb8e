"""``stewart-vibration report``: summary and plots from an MCAP written with real CDR bytes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from stewart_vibration.analysis import report_data, run_streams
from stewart_vibration.cli.main import main
from stewart_vibration.mcap_log import McapRunWriter


def _write_run(path, n=400, f_hz=20.0, dt=0.002):
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_JAZZY)
    T = ts.types
    Time, Header = T["builtin_interfaces/msg/Time"], T["std_msgs/msg/Header"]
    direction = np.array([0.3, 0.1, 0.95]) / np.linalg.norm([0.3, 0.1, 0.95])
    w = McapRunWriter(path)
    w.add_topic("/legs/joint_states", "sensor_msgs/msg/JointState", "[]")
    w.add_topic("/ground_truth/platform_pose", "geometry_msgs/msg/PoseStamped", "[]")
    w.add_topic("/legs/force_estimate", "sensor_msgs/msg/JointState", "[]")
    w.add_topic("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray", "[]")
    names = [f"leg_{i}" for i in range(1, 7)] + [f"vib_{i}" for i in range(1, 7)]
    for k in range(n):
        t = k * dt
        t_ns = 10**9 + round(t * 1e9)
        h = Header(Time(t_ns // 10**9, t_ns % 10**9), "base")
        s = np.sin(2 * np.pi * f_hz * t)
        pos = np.r_[0.3 + 1e-4 * s * np.ones(6), 5e-4 * s * np.ones(6)]
        effort = np.r_[40.0 + 2 * s * np.ones(6), np.zeros(6)]
        js = T["sensor_msgs/msg/JointState"](h, names, pos, np.zeros(12), effort)
        w.submit("/legs/joint_states", t_ns, bytes(ts.serialize_cdr(js, "sensor_msgs/msg/JointState")))
        est = T["sensor_msgs/msg/JointState"](h, names[:6], np.zeros(0), np.zeros(0), effort[:6] + 0.5)
        w.submit("/legs/force_estimate", t_ns, bytes(ts.serialize_cdr(est, "sensor_msgs/msg/JointState")))
        p = 5e-4 * s * direction + np.array([0, 0, 0.25])
        point, quat = T["geometry_msgs/msg/Point"](*p), T["geometry_msgs/msg/Quaternion"](0, 0, 0, 1)
        pose = T["geometry_msgs/msg/PoseStamped"](h, T["geometry_msgs/msg/Pose"](point, quat))
        w.submit("/ground_truth/platform_pose", t_ns, bytes(ts.serialize_cdr(pose, "geometry_msgs/msg/PoseStamped")))
        if k in (0, n - 1):
            text = "started" if k == 0 else "stopped"
            st = T["diagnostic_msgs/msg/DiagnosticStatus"](0, "vibration_planner", text, "", [])
            arr = T["diagnostic_msgs/msg/DiagnosticArray"](h, [st])
            w.submit("/diagnostics", t_ns, bytes(ts.serialize_cdr(arr, "diagnostic_msgs/msg/DiagnosticArray")))
    w.close()
    return direction


@pytest.mark.parametrize("n, batch, analysed_max_s", [(400, None, None), (12_000, 997, None), (12_000, 997, 10.0)])
def test_report_summary_and_plots(tmp_path, monkeypatch, n, batch, analysed_max_s):
    """The report of a clean 20 Hz vibration; the long one is read in small batches (its whole-run figures
    streamed, its plotted series as envelopes, its steady vibration read again on its own), and fitted over the
    middle of its steady part only when that is longer than the longest span analysed."""
    if batch:
        monkeypatch.setattr(run_streams, "BATCH_MESSAGES", batch)
    if analysed_max_s:
        monkeypatch.setattr(report_data, "ANALYSED_MAX_S", analysed_max_s)
    path = tmp_path / "run.mcap"
    direction = _write_run(path, n=n)
    out = tmp_path / "report"
    assert main(["report", str(path), "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["message_count"] == n * 3 + 2
    # the steady vibration: where the units move (from the first sample past 2 % of the peak to the last), less
    # 0.25 s of ramp at each end when it lasts over 1 s
    t = np.arange(n) * 0.002
    level = np.abs(5e-4 * np.sin(2 * np.pi * 20.0 * t))
    active = t[level > 0.02 * level.max()]
    trim = 0.25 if active[-1] - active[0] > 1.0 else 0.0
    assert summary["vibration_window_s"] == pytest.approx([active[0] + trim, active[-1] - trim], abs=1e-9)
    a, b = summary["vibration_window_s"]
    c, d = summary["analysed_window_s"]
    if analysed_max_s:
        assert (c + d) / 2 == pytest.approx((a + b) / 2) and d - c == pytest.approx(analysed_max_s)
        assert "its middle" in (out / "summary.md").read_text()
    else:
        assert (c, d) == (a, b)
    assert summary["leg_length_mean_m"]["leg_1"] == pytest.approx(0.3 + 1e-4 * np.sin(2 * np.pi * 20.0 * t).mean())
    # A clean, exactly sampled sine: the least-squares fit's golden-section search stops at a bracket of
    # 1e-9 f around the true frequency, and at that frequency error the fitted amplitude is off by
    # ~ (pi df T)^2 / 6 ~ 1e-18 relative; what is left is round-off.
    assert sorted(summary["vibration"]) == [f"vib_{i}" for i in range(1, 7)]
    for v in summary["vibration"].values():
        assert abs(v["frequency_hz"] - 20.0) <= 1e-9 * 20.0
        assert abs(v["amplitude_m"] - 5e-4) <= 1e-9 * 5e-4
    platform = summary["platform"]
    d = np.array(platform["vibration_direction"])
    assert abs(abs(d @ direction) - 1.0) < 1e-9
    assert platform["off_axis_ratio"] < 1e-9  # a pure line
    # the run summary's fit (line_vibration at the legs' fitted frequency) of a clean sine: exact to round-off
    assert abs(platform["frequency_hz"] - 20.0) <= 1e-9 * 20.0
    assert abs(platform["vibration_amplitude_m"] / 5e-4 - 1.0) <= 1e-9
    assert all(abs(e - 0.5) < 1e-9 for e in summary["force_error_rms_n"].values())
    assert [e["text"] for e in summary["events"]] == ["started", "stopped"]
    for name in ("leg_lengths.png", "vibration.png", "platform.png", "forces.png", "events.png"):
        assert (out / name).stat().st_size > 10_000
    assert "vib amplitude" in (out / "summary.md").read_text()


def test_a_long_series_is_plotted_as_its_envelope_with_every_peak():
    from stewart_vibration.analysis.run_plots import PLOT_BINS, envelope

    t = np.arange(1_800_000) / 500.0  # an hour at 500 Hz
    y = 2e-5 * np.sin(2 * np.pi * 35.0 * t)
    y[777_777], y[1_234_567] = 1e-3, -2e-3  # one-sample spikes must stay visible
    y[5] = np.nan
    te, ye = envelope(t, y)
    assert te.size == ye.size == 2 * PLOT_BINS
    assert ye.max() == 1e-3 and ye.min() == -2e-3
    assert np.all(np.diff(te) >= 0) and te[0] >= t[0] and te[-1] <= t[-1]
    spike = np.flatnonzero(ye == 1e-3)[0]  # drawn at its own time, within one bin
    assert abs(te[spike] - t[777_777]) <= t[-1] / PLOT_BINS
    short_t, short_y = envelope(t[:1000], y[:1000])
    np.testing.assert_array_equal(short_t, t[:1000])
    np.testing.assert_array_equal(short_y, y[:1000])


def test_a_report_that_fails_leaves_its_folder_as_it_was(tmp_path, monkeypatch):
    """The summary fails after figures were drawn from the run's data: no figure reaches --out (an older
    report's file there stays as it was), and nothing is left being drawn beside it."""
    import time

    from stewart_vibration.analysis import plot_pool, run_report

    path = tmp_path / "run.mcap"
    _write_run(path)
    out = tmp_path / "report"
    out.mkdir()
    (out / "summary.json").write_text('{"older": true}')

    def failing_summary(*_args):
        # with worker processes (two cores), the figures drawn from the data alone are written meanwhile: wait
        # for the first, wherever it goes, so a figure written straight into --out would be caught below
        deadline = time.monotonic() + 30
        while plot_pool.worker_count() > 1 and not list(out.rglob("*.png")) and time.monotonic() < deadline:
            time.sleep(0.01)
        raise ValueError("fewer than 4 ground-truth poses")

    monkeypatch.setattr(run_report, "summarize", failing_summary)
    with pytest.raises(ValueError, match="ground-truth poses"):
        run_report.write_report(path, out)
    assert sorted(p.name for p in out.iterdir()) == ["summary.json"]
    assert (out / "summary.json").read_text() == '{"older": true}'
