"""analysis.delivered against signals built here: a line vibration of known amplitude, direction, frequency and
leg phases, with noise; and too short a window says nothing."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.analysis.delivered import delivered_vibration

F = 35.0


def signals(direction, amplitude, frequency=F, phase_errors=None, noise=0.0, seconds=0.25, seed=1):
    rng = np.random.default_rng(seed)
    phase_errors = np.zeros(6) if phase_errors is None else phase_errors
    t = 12.0 + np.arange(0.0, seconds, 0.002)  # 500 Hz, absolute stamps
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    platform = 0.1 + np.outer(amplitude * np.sin(2 * np.pi * frequency * t), d)
    platform += noise * rng.standard_normal((t.size, 3))
    legs_amp = np.array([1.0, 0.8, 0.6, 0.9, 0.7, 0.5]) * amplitude
    legs_phase = np.array([0.0, np.pi, 0.0, np.pi, 0.0, np.pi])
    # the units follow with a common delay (a phase offset of every leg) plus each one's own error
    units = legs_amp * np.sin(2 * np.pi * frequency * (t[:, None] - 12.0) + legs_phase - 0.3 + phase_errors)
    return t, platform, units, legs_amp, legs_phase


def test_the_delivered_line_is_found_against_the_plan():
    planned = np.array([0.0, 0.0, 1.0])
    tilted = np.array([np.sin(np.radians(5.0)), 0.0, np.cos(np.radians(5.0))])
    t, p, u, amp, phase = signals(tilted, 60e-6, noise=0.05e-6)
    d = delivered_vibration(t, p, t, u, F, planned, amp, phase)
    assert d.known
    assert d.direction_error_rad == pytest.approx(np.radians(5.0), abs=np.radians(0.05))
    assert d.amplitude_m == pytest.approx(60e-6 * np.cos(np.radians(5.0)), rel=2e-3)  # along the planned line
    assert d.frequency_hz == pytest.approx(F, abs=0.05)
    assert d.phase_spread_rad == pytest.approx(0.0, abs=1e-9)  # a common delay is no spread


def test_the_phase_spread_is_the_largest_leg_error_about_their_mean():
    errors = np.radians([0.0, 0.0, 0.0, 0.0, 0.0, 12.0])
    t, p, u, amp, phase = signals([0, 0, 1], 60e-6, phase_errors=errors)
    d = delivered_vibration(t, p, t, u, F, [0, 0, 1], amp, phase)
    assert d.phase_spread_rad == pytest.approx(np.radians(10.0), abs=np.radians(0.01))  # 12 deg - mean 2 deg


def test_a_measured_frequency_off_the_plan_is_reported():
    t, p, u, amp, phase = signals([0, 0, 1], 60e-6, frequency=36.0, seconds=0.5)
    assert delivered_vibration(t, p, t, u, F, [0, 0, 1], amp, phase).frequency_hz == pytest.approx(36.0, abs=0.05)


def test_too_few_cycles_say_nothing():
    t, p, u, amp, phase = signals([0, 0, 1], 60e-6, seconds=0.05)  # under 2 cycles
    d = delivered_vibration(t, p, t, u, F, [0, 0, 1], amp, phase)
    assert not d.known and d.amplitude_m == 0.0 and d.frequency_hz == 0.0
    empty = delivered_vibration(np.empty(0), np.empty((0, 3)), np.empty(0), np.empty((0, 6)), F, [0, 0, 1], amp, phase)
    assert not empty.known
