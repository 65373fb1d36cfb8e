"""The run summary (analysis/vibration_figures.py, analysis/run_verdict.py) on synthetic signals: figures of
a perfect vibration, and a verdict that fails for every kind of figure it prints when that figure is off."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.analysis.run_verdict import check_bounds
from stewart_vibration.analysis.vibration_figures import summarize_vibration
from stewart_vibration.errors import ConfigError
from stewart_vibration.kinematics import inverse_kinematics
from stewart_vibration.paper import paper_pose
from stewart_vibration.runtime.scenario import DEFAULT_BOUNDS, load_scenario
from stewart_vibration.vibration.settings import default_settings, plan_vibration
from stewart_vibration.vibration.signals import platform_vibration_motion, sample_leg_vibration

START = 10.0  # t0 of the vibration (sim s)
RATE = 500.0  # states per second


def signals_of(robot, settings, leg_scale=None, leg_frequency=None, force_offset=0.0, pose_noise=None):
    """What a run records when the units do exactly what was planned (optionally spoilt)."""
    pose0 = paper_pose(robot)
    plan = plan_vibration(robot, pose0, settings, check_limits=False, method="linear")
    duration, ramp = settings["duration_s"], settings["ramp_s"]
    t = START - 1.0 + np.arange(int((duration + 2.0) * RATE)) / RATE
    vib = sample_leg_vibration(robot, plan, t - START, duration=duration, ramp_time=ramp, method="linear").position
    if leg_frequency is not None:  # leg 1 at another frequency
        other = plan_vibration(robot, pose0, dict(settings, frequency_hz=leg_frequency), check_limits=False,
                               method="linear")
        vib[:, 0] = sample_leg_vibration(robot, other, t - START, duration=duration, ramp_time=ramp,
                                         method="linear").position[:, 0]
    if leg_scale is not None:
        vib = vib * leg_scale
    motion = platform_vibration_motion(plan, t - START, duration=duration, ramp_time=ramp)
    poses = motion.pose + (0.0 if pose_noise is None else pose_noise(t))
    struts = np.broadcast_to(inverse_kinematics(robot, pose0), vib.shape)
    effort = 40.0 + 3.0 * np.sin(2 * np.pi * settings["frequency_hz"] * t)[:, None] * np.ones(6)
    return {
        "pose": (t, poses),
        "joints": (t, {"position": np.hstack([struts, vib]), "effort": np.hstack([effort, effort])}),
        "force_estimate": (t, {"effort": effort + force_offset}),
        "vibration_starts": np.array([START]),
    }


@pytest.fixture()
def settings(robot):
    return dict(default_settings(robot), duration_s=3.0)


def verdict(robot, settings, **spoil):
    summary = summarize_vibration(robot, signals_of(robot, settings, **spoil), paper_pose(robot), settings, START - 0.5)
    return summary, check_bounds({"moves": [], "vibrations": [summary]}, DEFAULT_BOUNDS)


def test_a_vibration_as_planned_passes_every_bound(robot, settings):
    summary, failures = verdict(robot, settings)
    assert failures == []
    assert summary["amplitude_error"] < 1e-6 and summary["direction_error_deg"] < 1e-4
    assert summary["off_axis_ratio"] < 1e-6 and max(summary["leg_amplitude_error"]) < 1e-6
    assert summary["leg_frequency_error_hz"] < 1e-6 and summary["force"]["worst_leg_relative"] < 1e-12
    # active at >= half amplitude: duration - ramp (half of each ramp), to one 35 Hz period
    assert abs(summary["active_duration_s"] - (settings["duration_s"] - settings["ramp_s"])) <= 1 / 35


@pytest.mark.parametrize("spoil, words", [
    ({"leg_scale": np.r_[1.05, np.ones(5)]}, "leg amplitude error"),
    ({"leg_frequency": 35.05}, "leg frequency error"),
    ({"force_offset": 0.2}, "force RMS error"),
    ({"pose_noise": lambda t: np.outer(np.cos(2 * np.pi * 35 * t), [0, 1.5e-6, 0, 0, 0, 0])}, "off-axis ratio"),
])
def test_each_kind_of_figure_fails_the_verdict_when_it_is_off(robot, settings, spoil, words):
    _, failures = verdict(robot, settings, **spoil)
    assert any(words in f for f in failures), failures


def test_the_summary_judges_the_settings_that_ran_never_defaults(robot, settings):
    """A setting missing from what the planner reported is an error, not silently the default."""
    reported = dict(settings)
    del reported["frequency_hz"]
    with pytest.raises(KeyError):
        summarize_vibration(robot, signals_of(robot, settings), paper_pose(robot), reported, START - 0.5)


def test_streams_and_lag_are_judged(robot):
    streams = {"worst_ratio": 1.0, "lost": 0, "nodes": {
        "kinematics": {"received": 10, "lost": 0, "processed": 10, "lag_p50_ms": 5.0, "lag_p99_ms": 900.0}}}
    failures = check_bounds({"moves": [], "vibrations": [], "streams": streams}, DEFAULT_BOUNDS)
    assert failures == ["kinematics: lag p99 900.0 ms exceeds 500 ms"]
    nan_move = {"name": "paper", "pose_error_m": float("nan"), "pose_error_deg": 0.0}
    assert check_bounds({"moves": [nan_move], "vibrations": []}, DEFAULT_BOUNDS)  # NaN is not within a bound


def test_a_scenario_vibration_follows_the_planner_duration_rule(robot, tmp_path):
    """duration_s 0 (until stop) is refused in a scenario (it must end); otherwise the planner's rule:
    at least two ramps."""
    for duration, ok in ((0.4, True), (0.39, False), (0.0, False)):
        path = tmp_path / "s.yaml"
        path.write_text(f"steps:\n  - vibrate: {{duration_s: {duration}, ramp_s: 0.2}}\n")
        if ok:
            assert load_scenario(robot, path).steps[0].parameters["duration_s"] == duration
        else:
            with pytest.raises(ConfigError, match="duration_s"):
                load_scenario(robot, path)
