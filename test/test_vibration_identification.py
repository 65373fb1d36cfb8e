"""vibration.frequency_response and vibration.unit_identification: stepped-sine responses against synthetic
signals of known response (closed forms), the IMU's motion response, interpolation, quality and the file."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.errors import ConfigError, InvalidInputError
from stewart_vibration.kinematics.rotations import rotation_from_rpy
from stewart_vibration.vibration.frequency_response import platform_motion_response, sine_response
from stewart_vibration.vibration.unit_identification import (
    VibrationIdentification,
    interpolate_response,
    load_identification,
    quality_problems,
    save_identification,
)

RATE, F, A = 2000.0, 35.0, 20e-6


def record(seconds: float = 1.0, rate: float = RATE):
    return np.arange(int(seconds * rate)) / rate


def sine(t, complex_amplitude, frequency=F):
    """|c| sin(2 pi f t + arg c)."""
    return np.abs(complex_amplitude) * np.sin(2 * np.pi * frequency * t + np.angle(complex_amplitude))


def test_the_response_of_noise_free_outputs_is_exact_with_full_coherence():
    t = record()
    truth = np.array([1.2 * np.exp(0.3j), 0.05 * np.exp(-2.9j), 0.0])
    demand = sine(t, A * np.exp(0.7j))
    outputs = np.column_stack([sine(t, A * np.exp(0.7j) * h) for h in truth]) + [1e-3, -2e-4, 0.0]  # offsets
    result = sine_response(t, demand, outputs, F, blocks=5)
    np.testing.assert_allclose(result.response, truth, atol=1e-9)
    np.testing.assert_allclose(result.coherence, 1.0, atol=1e-9)
    assert result.blocks == 5 and np.all(result.uncertainty < 1e-9)


def test_noise_lowers_the_coherence_and_the_uncertainty_is_its_standard_error():
    rng = np.random.default_rng(3)
    t = record(4.0)
    truth = 0.8 * np.exp(-0.4j)
    sigma = 2e-6
    demand = sine(t, A)
    estimates, uncertainties, coherences = [], [], []
    for _ in range(40):
        out = sine(t, A * truth) + rng.normal(0, sigma, t.size)
        r = sine_response(t, demand, out, F, blocks=8)
        estimates.append(r.response[0])
        uncertainties.append(r.uncertainty[0])
        coherences.append(r.coherence[0])
    spread = np.sqrt(np.mean(np.abs(np.array(estimates) - truth) ** 2))
    # the least-squares amplitude of N samples with white noise sigma: std sqrt(2/N) sigma per quadrature
    theory = np.sqrt(2 * 2.0 / t.size) * sigma / A
    assert 0.7 < spread / theory < 1.4
    assert 0.6 < np.mean(uncertainties) / theory < 1.5
    assert 0.9 < np.mean(coherences) < 1.0
    # noise far above the response: the coherence says so
    noisy = sine_response(t, demand, sine(t, A * truth) + rng.normal(0, 300 * sigma, t.size), F, blocks=8)
    assert noisy.coherence[0] < 0.5


def test_a_record_too_short_or_a_demand_without_the_frequency_is_refused():
    t = record(0.05)
    with pytest.raises(InvalidInputError, match="periods"):
        sine_response(t, sine(t, A), sine(t, A)[:, None], F, blocks=4)
    t = record()
    with pytest.raises(InvalidInputError, match="not a sine at 35 Hz"):
        sine_response(t, sine(t, A, frequency=50.0), sine(t, A)[:, None], F)
    with pytest.raises(InvalidInputError, match="finite"):
        sine_response(t, np.full(t.size, np.nan), sine(t, A)[:, None], F)


def test_the_imu_response_gives_the_platform_motion_in_the_base_frame():
    """A platform moving dp(t), dphi(t) (base frame) seen by an IMU at its origin with platform axes, as an
    integrate-and-dump accelerometer over its 2 ms sample period: the mean over that period of
    R(t)^T (dp'' - g), R(t) = (I + [dphi]x) R0, and the angular rate R0^T dphi'; back to the motion."""
    dt, period = 1e-5, 0.002
    fine = np.arange(0.0, 1.0 + period, dt)
    rot = rotation_from_rpy([0.2, -0.1, 0.3])
    gravity = np.array([0.0, 0.0, -9.80665])
    motion = np.array([3e-6 * np.exp(0.2j), -1e-6 * np.exp(0.2j), 6e-5 * np.exp(0.2j), 1e-4j, 0.0, 2e-5])
    w = 2 * np.pi * F
    accel_base = np.column_stack([sine(fine, -w * w * c) for c in motion[:3]])
    dphi = np.column_stack([sine(fine, c) for c in motion[3:]])
    specific = accel_base - gravity + np.cross(dphi, -gravity)  # (I - [dphi]x)(a - g), to first order
    specific = specific @ rot  # R0^T per row
    per_sample = int(round(period / dt))
    t = fine[per_sample::per_sample][:-1]
    cumulative = np.cumsum(specific, axis=0) * dt
    accel = (cumulative[per_sample::per_sample] - cumulative[:-per_sample:per_sample])[:-1] / period
    gyro = np.column_stack([sine(t, 1j * w * c) for c in motion[3:]]) @ rot
    demand = sine(t, 1.0 + 0j)
    r_acc = sine_response(t, demand, accel, F).response
    r_gyro = sine_response(t, demand, gyro, F).response
    found = platform_motion_response(r_acc, r_gyro, F, rot, gravity, accel_average_s=period)
    np.testing.assert_allclose(found, motion, atol=2e-3 * np.abs(motion).max())
    # without the device's averaging and gravity the rocking platform's translation comes out wrong
    naive = platform_motion_response(r_acc, r_gyro, F, rot)
    assert np.abs(naive[:3] - motion[:3]).max() > 0.05 * np.abs(motion[:3]).max()


def test_interpolation_is_exact_at_the_identified_frequencies_and_linear_in_magnitude_and_phase():
    f = np.array([20.0, 30.0, 40.0])
    h = np.array([[1.0 * np.exp(3.1j)], [2.0 * np.exp(-3.1j)], [1.0 + 0j]])  # the phase crosses +-pi
    for k in range(3):
        np.testing.assert_allclose(interpolate_response(f, h, f[k]), h[k])
    mid = interpolate_response(f, h, 25.0)[0]
    assert abs(abs(mid) - 1.5) < 1e-12
    assert abs(np.angle(mid) - np.pi) < 1e-12  # half way the short way round (3.1 -> 3.183), not through 0
    with pytest.raises(InvalidInputError, match="outside the identified band"):
        interpolate_response(f, h, 45.0)


def identification(unit_coherence=0.999, uncertainty=1e-4) -> VibrationIdentification:
    freqs = np.array([30.0, 35.0, 40.0])
    units = np.array([[1.1 * np.exp(-0.2j)] * 6, [1.2 * np.exp(-0.3j)] * 6, [1.3 * np.exp(-0.4j)] * 6])
    platform = np.stack([np.eye(6) * u[0] + 0.01j for u in units])
    return VibrationIdentification(
        pose=np.array([0.0, 0.0, 0.16, 0.0, 0.0, 0.0]), frequencies=freqs, amplitude_m=5e-6,
        unit_response=units, unit_coherence=np.full((3, 6), unit_coherence),
        unit_uncertainty=np.full((3, 6), uncertainty), platform_response=platform,
        platform_coherence=np.full((3, 6, 6), 0.99), platform_uncertainty=np.full((3, 6, 6), uncertainty / 6),
        provenance={"date": "2026-12-05", "method": "stepped sine"})


def test_quality_accepts_a_clean_identification_and_names_what_is_poor():
    assert quality_problems(identification()) == []
    problems = quality_problems(identification(unit_coherence=0.8))
    assert len(problems) == 18 and problems[0].startswith("unit 1 at 30 Hz: coherence 0.800")
    assert any("uncertain by" in p for p in quality_problems(identification(uncertainty=0.1)))


def test_the_file_round_trips_and_a_wrong_file_is_refused(tmp_path):
    ident = identification()
    path = save_identification(tmp_path / "units.yaml", ident)
    back = load_identification(path)
    for name in ("pose", "frequencies", "unit_response", "unit_coherence", "platform_response",
                 "platform_uncertainty"):
        np.testing.assert_array_equal(getattr(back, name), getattr(ident, name))
    assert back.provenance == ident.provenance and back.amplitude_m == ident.amplitude_m
    np.testing.assert_allclose(back.unit_response_at(32.5), ident.unit_response_at(32.5))
    (tmp_path / "other.yaml").write_text("kind: robot\n")
    with pytest.raises(InvalidInputError, match="not a vibration identification"):
        load_identification(tmp_path / "other.yaml")
    text = path.read_text().replace("frequencies_hz:", "frequencies:")
    (tmp_path / "broken.yaml").write_text(text)
    with pytest.raises(InvalidInputError, match="frequencies_hz"):
        load_identification(tmp_path / "broken.yaml")
    with pytest.raises(ConfigError):
        load_identification(tmp_path / "missing.yaml")
    with pytest.raises(InvalidInputError, match="platform_response"):
        VibrationIdentification(**{**ident.__dict__, "platform_response": np.zeros((3, 6))})
