"""The sensed leg lengths against a delayed sinusoid's closed form: carried forward by the sensor's latency, a
unit's reported displacement is the present one to second order."""

from __future__ import annotations

import numpy as np

from stewart_vibration.estimation.sensed_lengths import sensed_leg_lengths


def test_a_delayed_unit_reading_is_carried_to_the_present():
    w, latency, amplitude = 2 * np.pi * 35.0, 0.0005, 60e-6
    t = np.linspace(0.0, 0.1, 201)[:, None] * np.ones(6)
    struts = np.full_like(t, 0.17) + 2e-6 * np.sin(w * t + np.pi)  # the struts' own small motion: not delayed
    reported = amplitude * np.sin(w * (t - latency))  # the unit sensor: the reading of latency s ago
    rates = amplitude * w * np.cos(w * (t - latency))
    truth = struts + amplitude * np.sin(w * t)
    carried = sensed_leg_lengths(struts, reported, rates, latency)
    assert np.abs(carried - truth).max() <= 0.6 * (w * latency) ** 2 * amplitude  # second order: 3e-10 m
    as_reported = sensed_leg_lengths(struts, reported, rates, 0.0)
    assert np.abs(as_reported - truth).max() > 0.1 * amplitude  # 6.3 deg of phase at 35 Hz


def test_without_units_or_rates_the_readings_are_summed():
    struts, units = np.full((3, 6), 0.17), np.full((3, 6), 1e-5)
    assert np.array_equal(sensed_leg_lengths(struts, None, None, 0.001), struts)
    rates = np.full((3, 6), np.nan)  # a state without rates: not carried
    np.testing.assert_allclose(sensed_leg_lengths(struts, units, rates, 0.001), struts + units)
