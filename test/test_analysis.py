"""Run analysis on synthetic signals with known answers."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.analysis.fits import (
    direction_error_deg,
    dominant_sinusoid,
    fit_sinusoid,
    force_error,
    leg_phase_offsets_deg,
    line_vibration,
    phase_error_to_0_or_pi_deg,
)
from stewart_vibration.errors import InvalidInputError


def test_fit_recovers_amplitude_phase_offset_with_drift():
    t = np.arange(0, 1.0, 1 / 500)
    amps = np.array([1.0, 2.0, 0.5])
    phases = np.array([0.3, -2.0, np.pi - 0.01])
    x = amps * np.sin(2 * np.pi * 35 * t[:, None] + phases) + 0.1 + 0.05 * t[:, None]
    fit = fit_sinusoid(t, x, 35.0)
    assert np.allclose(fit.amplitude, amps, rtol=1e-9)
    assert np.allclose(np.angle(np.exp(1j * (fit.phase - phases))), 0, atol=1e-9)
    assert np.all(fit.residual_rms < 1e-12)


def test_fit_needs_four_samples():
    """Four unknowns (sin, cos, offset, drift): four samples determine them exactly, three are refused."""
    t = np.array([0.0, 0.004, 0.011, 0.019])
    x = 0.7 * np.sin(2 * np.pi * 35 * t + 0.4) - 0.2 + 3.0 * (t - t.mean())
    fit = fit_sinusoid(t, x, 35.0)
    assert fit.amplitude == pytest.approx(0.7, rel=1e-9) and fit.offset == pytest.approx(-0.2, rel=1e-9)
    with pytest.raises(InvalidInputError, match=">= 4"):
        fit_sinusoid(t[:3], x[:3], 35.0)


def test_line_vibration_direction_amplitude_and_ellipse():
    t = np.arange(0, 1.0, 1 / 500)
    u = np.array([0.3, -0.2, 0.9])
    u /= np.linalg.norm(u)
    pos = 61e-6 * np.sin(2 * np.pi * 35 * t + 1.0)[:, None] * u + [0.002, 0.002, 0.162]
    line = line_vibration(t, pos, 35.0)
    assert direction_error_deg(line.direction, u) < 1e-6
    assert line.amplitude == pytest.approx(61e-6, rel=1e-9)
    assert line.off_axis_ratio < 1e-9
    v = np.cross(u, [1.0, 0, 0])
    v /= np.linalg.norm(v)  # perpendicular to u, in quadrature: an ellipse with axes 61 and 10 um
    ellipse = pos + 10e-6 * np.cos(2 * np.pi * 35 * t + 1.0)[:, None] * v
    assert line_vibration(t, ellipse, 35.0).off_axis_ratio == pytest.approx(10 / 61, rel=1e-9)


def test_direction_error_is_sign_free():
    assert direction_error_deg([0, 0, 1], [0, 0, -1]) == pytest.approx(0.0)
    assert direction_error_deg([0, 1, 0], [0, 0, 1]) == pytest.approx(90.0)


def test_leg_phases_and_distance_to_0_or_pi():
    t = np.arange(0, 1.0, 1 / 500)
    phases = np.array([0.2, 0.2 + np.pi, 0.2, 0.2 + np.radians(1.0), 0.2 - np.pi, 0.2])
    gains = np.array([0.9, 0.5, 0.8, 0.7, 0.6, 0.95])
    x = gains * np.sin(2 * np.pi * 35 * t[:, None] + phases)
    offsets = leg_phase_offsets_deg(fit_sinusoid(t, x, 35.0))
    err = phase_error_to_0_or_pi_deg(offsets)
    assert np.allclose(err, [0, 0, 0, 1.0, 0, 0], atol=1e-7)


def test_force_error_relative_to_amplitude():
    t = np.arange(0, 1.0, 1 / 500)
    meas = 20 + 5 * np.sin(2 * np.pi * 35 * t)[:, None] * np.ones(6)
    est = meas + 0.05  # 0.05 N bias
    out = force_error(t, est, t, meas, 35.0)
    assert np.allclose(out["rms_error_n"], 0.05)
    assert out["worst_leg_relative"] == pytest.approx(0.01, rel=1e-6)
    assert out["worst_leg_vs_largest_amplitude"] == pytest.approx(0.01, rel=1e-6)
    # only the measured samples inside the estimate's span count; four are enough, three are not
    short = force_error(t[10:14], est[10:14], t, meas)
    assert short["samples"] == 4 and np.allclose(short["rms_error_n"], 0.05)
    with pytest.raises(InvalidInputError, match="do not overlap"):
        force_error(t[10:13], est[10:13], t, meas)


@pytest.mark.parametrize("frequency", [35.0, 33.37, 7.9])
def test_dominant_sinusoid_resolves_frequency_far_below_the_fft_bin(frequency):
    """2.5 s of jittered samples (FFT bin 0.4 Hz) with a 2 % second harmonic, an offset and noise."""
    rng = np.random.default_rng(3)
    t = np.sort(rng.uniform(0.0, 2.5, 1250))
    x = 53e-6 * np.sin(2 * np.pi * frequency * t + 0.7) + 1e-6 * np.sin(2 * np.pi * 2 * frequency * t)
    x += 1e-3 + rng.normal(scale=1e-7, size=t.size)
    amplitude, found = dominant_sinusoid(t, x)
    assert abs(found - frequency) < 1e-3
    assert amplitude == pytest.approx(53e-6, rel=1e-3)


def test_dominant_sinusoid_of_too_few_samples_is_zero():
    assert dominant_sinusoid([0.0, 1.0], [1.0, 2.0]) == (0.0, 0.0)



def test_a_leg_whose_force_does_not_vibrate_is_judged_against_the_largest_amplitude():
    # along some directions a leg's force hardly vibrates: its own relative error is unbounded, the error
    # against the vibration's force scale (the largest leg's amplitude, here 8 N) is not
    t = np.arange(0, 1.0, 1 / 500)
    amplitudes = np.array([8.0, 5.0, 0.0, 2.0, 1e-3, 4.0])
    meas = 20 + np.sin(2 * np.pi * 35 * t)[:, None] * amplitudes
    bias = np.array([0.04, 0.02, 0.06, 0.01, 0.03, 0.0])
    out = force_error(t, meas + bias, t, meas, 35.0)
    assert out["worst_leg_vs_largest_amplitude"] == pytest.approx(0.06 / 8.0, rel=1e-6)
    assert out["relative_rms_error"][4] == pytest.approx(30.0, rel=1e-3)
    assert out["worst_leg_relative"] > 1e3  # leg 3's fitted amplitude is rounding noise, or zero
