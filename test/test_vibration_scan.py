"""A long vibration summarised without holding it (analysis/vibration_scan.py, vibration/sine_fit.SineSums): the
sums of its streamed middle plus its held ends give the figures of the whole vibration held, checked against
fit_sinusoid and summarize_vibration over every sample, and through a recorded MCAP read twice."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.analysis.report_scan import ForceErrorScan
from stewart_vibration.analysis.run_signals import load_signals
from stewart_vibration.analysis.vibration_figures import summarize_vibration, vibration_frame
from stewart_vibration.analysis.vibration_scan import EDGE_S, SteadyStream, held_windows, stream_steady, streamed_span
from stewart_vibration.errors import InvalidInputError
from stewart_vibration.mcap_log.writer import BagFileWriter
from stewart_vibration.messages.joint_states import JointStateEncoder
from stewart_vibration.messages.joint_trajectory import encode_joint_trajectory
from stewart_vibration.messages.stamped_doubles import PoseStampedEncoder
from stewart_vibration.paper import paper_pose
from stewart_vibration.robot import LEG_NAMES, VIB_NAMES
from stewart_vibration.vibration.settings import default_settings, plan_vibration
from stewart_vibration.vibration.sine_fit import SineSums, fit_sinusoid

RATE, START, DURATION = 500.0, 5.0, 75.0  # states per s; the vibration's t0 and duration (s, ramps included)


@pytest.mark.parametrize("batches", [1, 7, 1001])
def test_sums_in_any_batches_and_order_fit_as_fit_sinusoid_does(batches):
    rng = np.random.default_rng(batches)
    t = np.sort(rng.uniform(100.0, 3700.0, 50_000))
    x = (0.17 + 6e-5 * np.sin(2 * np.pi * 35.0 * t[:, None] + [0.1, 1.0, -2.5]) + 1e-9 * (t[:, None] - 100.0)
         + 1e-7 * rng.normal(size=(t.size, 3)))
    reference = fit_sinusoid(t, x, 35.0)
    parts = np.array_split(rng.permutation(t.size), batches)
    sums = SineSums(35.0, 3, (100.0, 3700.0))
    for part in parts[: len(parts) // 2 + 1]:
        sums.add(t[part], x[part])
    rest = SineSums(35.0, 3, (100.0, 3700.0))
    for part in parts[len(parts) // 2 + 1:]:
        rest.add(t[part], x[part])
    fit = sums.merged(rest).fit() if batches > 1 else sums.fit()
    np.testing.assert_allclose(fit.amplitude, reference.amplitude, rtol=1e-10)
    np.testing.assert_allclose(fit.phase, reference.phase, atol=1e-9)
    np.testing.assert_allclose(fit.offset, reference.offset, rtol=1e-12)
    np.testing.assert_allclose(fit.residual_rms, reference.residual_rms, rtol=1e-6)


def test_sums_refuse_what_fit_sinusoid_refuses():
    sums = SineSums(35.0, 1, (0.0, 1.0))
    sums.add(np.arange(3) * 0.01, np.zeros((3, 1)))
    with pytest.raises(InvalidInputError):
        sums.fit()  # three samples
    sums.add(np.array([0.5, 0.6]), np.array([[np.nan], [0.0]]))
    with pytest.raises(InvalidInputError):
        sums.fit()  # five samples, one of them not finite


def test_only_a_vibration_longer_than_a_minute_is_streamed_and_its_ends_stay_held():
    windows, spans = held_windows([(5.0, 3.0), (20.0, 100.0)], 1.5)
    assert spans == [None, (20.0 + EDGE_S, 120.0 - EDGE_S)]
    assert windows == [(3.5, 9.5), (18.5, 20.0 + EDGE_S), (120.0 - EDGE_S, 121.5)]
    assert held_windows([(20.0, 100.0)], 1.5, streaming=False) == ([(18.5, 121.5)], [None])
    assert streamed_span(0.0, 60.0) is None


def _recording(robot, settings):
    """A run's 500 Hz streams (true and sensed joint states, true and estimated poses, force estimates) over a
    vibration at the paper's pose that is not quite the plan: noise, a leg off in amplitude, a slow drift, a
    force model off by a constant and a share of the oscillation."""
    rng = np.random.default_rng(3)
    plan = plan_vibration(robot, paper_pose(robot), settings, check_limits=False, method="linear")
    t = START - 2.0 + np.arange(int((DURATION + 4.0) * RATE)) / RATE
    w, ramp = 2 * np.pi * settings["frequency_hz"], settings["ramp_s"]
    envelope = np.clip(np.minimum(t - START, START + DURATION - t) / ramp, 0.0, 1.0)
    wave = envelope * np.sin(w * (t - START))
    vib = wave[:, None] * plan.gains * plan.amplitude * [1.0, 1.02, 1.0, 0.99, 1.0, 1.0]
    struts = 0.17 + 1e-7 * (t[:, None] - START) + 2e-8 * rng.normal(size=(t.size, 6))
    pose = np.zeros((t.size, 6))
    pose[:, :3] = (0.3 + wave[:, None] * plan.amplitude * plan.direction + 1e-7 * rng.normal(size=(t.size, 3)))
    effort = 40.0 + 3.0 * wave[:, None] * np.ones(6)
    estimate = effort * 1.01 + 0.2 + 0.05 * rng.normal(size=effort.shape)
    sensed = np.hstack([struts, vib]) + 5e-8 * rng.normal(size=(t.size, 12))
    return t, {"truth": np.hstack([struts, vib]), "sensed": sensed, "effort": np.hstack([effort, effort]),
               "pose": pose, "estimated_pose": pose + 1e-6 * rng.normal(size=pose.shape), "estimate": estimate}


def _signals(t, rec, keep):
    return {"pose": (t[keep], rec["pose"][keep]), "pose_estimate": (t[keep], rec["estimated_pose"][keep]),
            "joints": (t[keep], {"position": rec["truth"][keep], "effort": rec["effort"][keep]}),
            "sensed_joints": (t[keep], {"position": rec["sensed"][keep]}),
            "force_estimate": (t[keep], {"effort": rec["estimate"][keep]}), "vibration_starts": np.array([START])}


def _assert_same_figures(got, want, path=""):
    """Every figure of two summaries alike: counts and flags exactly, measured values to rounding: 1e-8 relative,
    and near 0 angles to 1e-7 deg (a direction error from an arccos) and ratios to 1e-9 (an off-axis ratio is a
    small singular value over a large one)."""
    if isinstance(want, dict):
        assert set(got) == set(want), path
        for key in want:
            _assert_same_figures(got[key], want[key], f"{path}/{key}")
    elif isinstance(want, (bool, int, np.bool_, np.integer)) or want is None:
        assert got == want, path
    else:
        np.testing.assert_allclose(np.asarray(got, float), np.asarray(want, float), rtol=1e-8,
                                   atol=1e-7 if path.endswith("_deg") else 1e-9 if "ratio" in path else 1e-12,
                                   err_msg=path)


@pytest.fixture()
def settings(robot):
    return dict(default_settings(robot), duration_s=DURATION)


@pytest.mark.parametrize("batch", [997, 20_000])
def test_held_ends_and_a_streamed_middle_give_the_figures_of_the_whole_vibration(robot, settings, batch):
    t, rec = _recording(robot, settings)
    whole = summarize_vibration(robot, _signals(t, rec, np.ones(t.size, bool)), paper_pose(robot), settings, START)
    lo, hi = streamed_span(START, DURATION)
    held = _signals(t, rec, (t <= lo) | (t >= hi))
    frame = vibration_frame(robot, held, paper_pose(robot), settings, START)
    stream = SteadyStream(frame, (lo, hi))
    for at in range(0, t.size, batch):  # the whole run streams past; the stream sums its middle only
        part = slice(at, at + batch)
        stream.true_states(t[part], {"position": rec["truth"][part], "effort": rec["effort"][part]})
        stream.sensed_states(t[part], {"position": rec["sensed"][part]})
        stream.true_poses(t[part], rec["pose"][part])
        stream.pose_estimates(t[part], rec["estimated_pose"][part])
        stream.force_estimates(t[part], {"effort": rec["estimate"][part]})
    assert stream.hinge.count == np.count_nonzero((t > lo) & (t < hi) & (t >= frame.window[0])
                                                  & (t <= frame.window[1]))
    streamed = summarize_vibration(robot, held, paper_pose(robot), settings, START, stream)
    _assert_same_figures(streamed, whole)
    # the figures are not trivially alike: the spoilt leg and the force model show
    assert 0.015 < whole["leg_amplitude_error"][1] < 0.025 and whole["force"]["worst_leg_relative"] > 0.01
    # and the held ends alone give other figures: the middle's sums count
    ends = summarize_vibration(robot, held, paper_pose(robot), settings, START)
    assert ends["window_samples"] < whole["window_samples"] / 3


def test_the_force_error_of_two_parts_is_that_of_the_whole():
    rng = np.random.default_rng(5)
    t = np.arange(4000) / 500.0
    measured = 40.0 + 3.0 * np.sin(2 * np.pi * 35.0 * t)[:, None] + 0.1 * rng.normal(size=(t.size, 6))
    estimate = measured + 0.3 * rng.normal(size=measured.shape)
    whole = ForceErrorScan(frequency=35.0, window=(0.0, 8.0))
    whole.add_estimates(t, estimate)
    whole.add_measured(t, measured)
    first, second = ForceErrorScan(frequency=35.0, window=(0.0, 8.0)), ForceErrorScan(frequency=35.0,
                                                                                        window=(0.0, 8.0))
    for scan, part in ((first, slice(0, 1500)), (second, slice(1500, None))):
        scan.add_estimates(t[part], estimate[part])
        scan.add_measured(t[part], measured[part])
    want, got = whole.result(), first.combined(second)
    for key in ("rms_error_n", "force_amplitude_n", "worst_leg_relative", "samples"):
        np.testing.assert_allclose(got[key], want[key], rtol=1e-9)
    amplitude = fit_sinusoid(t, measured, 35.0).amplitude  # the fitted oscillation, not half the peak-to-peak
    np.testing.assert_allclose(want["force_amplitude_n"], amplitude, rtol=1e-9)


def _write_mcap(path, t, rec):
    writer = BagFileWriter(path)
    state, pose_type = "sensor_msgs/msg/JointState", "geometry_msgs/msg/PoseStamped"
    topics = {"legs/joint_states": state, "ground_truth/joint_states": state, "ground_truth/platform_pose": pose_type,
              "platform/pose_estimate": pose_type, "legs/force_estimate": state,
              "vibration/joint_trajectory": "trajectory_msgs/msg/JointTrajectory"}
    for name, type_name in topics.items():
        writer.add_topic("/stewart/" + name, type_name, "[]")
    states, forces = JointStateEncoder(LEG_NAMES + VIB_NAMES, "base"), JointStateEncoder(LEG_NAMES, "base",
                                                                                         fields=("effort",))
    pose = PoseStampedEncoder("base")
    for i, ti in enumerate(t):
        log = round(ti * 1e9) + 300_000
        if abs(ti - START) < 0.5 / RATE:
            writer.write("/stewart/vibration/joint_trajectory", log,
                         encode_joint_trajectory(VIB_NAMES, START, [0.0, 1.0], np.zeros((2, 6))))
        for name, position in (("legs/joint_states", rec["sensed"][i]), ("ground_truth/joint_states", rec["truth"][i])):
            writer.write("/stewart/" + name, log, states.encode(ti, position, np.zeros(12), rec["effort"][i]))
        for name, key in (("ground_truth/platform_pose", "pose"), ("platform/pose_estimate", "estimated_pose")):
            writer.write("/stewart/" + name, log, pose.encode(ti, rec[key][i, :3], [0.0, 0.0, 0.0, 1.0]))
        writer.write("/stewart/legs/force_estimate", log, forces.encode(ti, effort=rec["estimate"][i]))
    writer.finish()


def test_a_recorded_long_vibration_read_twice_has_the_figures_of_it_read_whole(robot, settings, tmp_path):
    t, rec = _recording(robot, settings)
    path = tmp_path / "long.mcap"
    _write_mcap(path, t, rec)
    whole_signals = load_signals(path)
    whole = summarize_vibration(robot, whole_signals, paper_pose(robot), settings, START)
    windows, spans = held_windows([(START, DURATION)], 1.5)
    held = load_signals(path, windows=windows)
    assert held["joints"][0].size < 0.35 * whole_signals["joints"][0].size  # the middle is not held
    frame = vibration_frame(robot, held, paper_pose(robot), settings, START)
    (stream,) = stream_steady(path, [(frame, spans[0])])
    _assert_same_figures(summarize_vibration(robot, held, paper_pose(robot), settings, START, stream), whole)
