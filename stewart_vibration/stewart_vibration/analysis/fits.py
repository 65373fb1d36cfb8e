"""Run analysis (pure numpy): what a vibration actually did, from recorded signals.

Least-squares sinusoid fits at a known frequency, the platform's vibration
direction and amplitude from its ground-truth positions, the legs' relative
phases, and the error of estimated against measured leg forces.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np

from ..errors import InvalidInputError
from ..kinematics.rotations import wrap_angle
from ..vibration.sine_fit import SinusoidFit, fit_sinusoid


def dominant_sinusoid(times, signal) -> tuple[float, float]:
    """(amplitude, frequency Hz) of the strongest sinusoid in ``signal`` [n] over ``times`` [n] (s).

    The FFT peak of the (uniformly resampled, Hann-windowed) signal gives the
    frequency to one bin, 1/T; a golden-section search within +-1 bin then
    minimises the residual of the least-squares sinusoid fit (fit_sinusoid),
    which resolves the frequency far below the bin width.

    Args:
        times: increasing sample times [n] (s).
        signal: samples [n].

    Returns:
        (amplitude (units of ``signal``), frequency (Hz)); (0.0, 0.0) for fewer than 8 samples or a
        time span <= 0.

    Raises:
        InvalidInputError: ``signal`` has a non-finite value (``fit_sinusoid``).
    """
    t = np.asarray(times, dtype=float)
    x = np.asarray(signal, dtype=float)
    if t.size < 8 or t[-1] <= t[0]:
        return 0.0, 0.0
    grid = np.linspace(t[0], t[-1], t.size)
    y = np.interp(grid, t, x) - x.mean()
    spec = np.abs(np.fft.rfft(y * np.hanning(y.size)))
    bin_hz = 1.0 / (grid[1] - grid[0]) / y.size
    k = int(np.argmax(spec[1:])) + 1

    def misfit(f: float) -> float:
        return float(fit_sinusoid(t, x, f).residual_rms)

    low, high = max((k - 1) * bin_hz, 0.5 * bin_hz), (k + 1) * bin_hz
    ratio = (np.sqrt(5.0) - 1.0) / 2.0
    a, b = high - ratio * (high - low), low + ratio * (high - low)
    fa, fb = misfit(a), misfit(b)
    while high - low > 1e-9 * max(high, 1.0):
        if fa < fb:
            high, b, fb = b, a, fa
            a = high - ratio * (high - low)
            fa = misfit(a)
        else:
            low, a, fa = a, b, fb
            b = low + ratio * (high - low)
            fb = misfit(b)
    freq = 0.5 * (low + high)
    return float(fit_sinusoid(t, x, freq).amplitude), float(freq)


@dataclass(frozen=True)
class LineVibration:
    """Principal direction (unit, base frame), amplitude (m), off-axis ratio of a vibration."""

    direction: np.ndarray
    amplitude: float
    off_axis_ratio: float


def line_vibration(times, positions, frequency: float) -> LineVibration:
    """Direction and amplitude of the fundamental of positions [n, 3] (m).

    The fundamental is Re(c e^{i w t}) with c in C^3; its principal axis is the
    first left singular vector of [Re c, Im c] (3 x 2), the amplitude the first
    singular value, and the off-axis ratio sigma2 / sigma1 (0 for a line).

    Args:
        times: sample times [n] (s).
        positions: platform positions [n, 3] (m, base frame).
        frequency: the vibration frequency (Hz).

    Returns:
        LineVibration: direction (3,) unit (base frame, sign arbitrary), amplitude (m), off_axis_ratio.

    Raises:
        InvalidInputError: fewer than 4 samples, or a non-finite position (``fit_sinusoid``).
    """
    return line_of_fit(fit_sinusoid(times, positions, frequency))


def line_of_fit(fit: SinusoidFit) -> LineVibration:
    """The LineVibration of a fit of positions [n, 3] (``fit_sinusoid``): the principal axis of its complex
    amplitude (see ``line_vibration``)."""
    c = fit.complex_amplitude
    u, sv, _ = np.linalg.svd(np.stack([c.real, c.imag], axis=1))
    return LineVibration(direction=u[:, 0], amplitude=float(sv[0]), off_axis_ratio=float(sv[1] / sv[0]))


def direction_error_deg(measured, expected) -> float:
    """Angle (deg) between two line directions, sign-free (a line has no sign).

    Args:
        measured: a non-zero direction (3,), any length.
        expected: a non-zero direction (3,), any length.

    Returns:
        The angle between the lines (deg, in [0, 90]).
    """
    a = np.asarray(measured, dtype=float)
    b = np.asarray(expected, dtype=float)
    cos = cast(float, abs(float(a @ b)) / (np.linalg.norm(a) * np.linalg.norm(b)))  # numpy types it floating
    return float(np.degrees(np.arccos(min(cos, 1.0))))


def leg_phase_offsets_deg(fit: SinusoidFit, reference_leg: int | None = None) -> np.ndarray:
    """Each leg's phase relative to the reference leg (largest amplitude by default), deg in (-180, 180].

    Args:
        fit: SinusoidFit of the leg signals (phase and amplitude [6]).
        reference_leg: index (0-based) of the reference leg; None: the leg with the largest amplitude.

    Returns:
        Phase offsets [6] (deg, in (-180, 180]); 0 for the reference leg.
    """
    ref = int(np.argmax(fit.amplitude)) if reference_leg is None else reference_leg
    return phase_offsets_deg(fit.phase, ref)


def phase_offsets_deg(phases, reference: int) -> np.ndarray:
    """Phases [6] (rad) relative to ``phases[reference]``, deg in (-180, 180]."""
    phases = np.asarray(phases, dtype=float)
    return np.degrees(wrap_angle(phases - phases[reference]))


def phase_error_to_0_or_pi_deg(offsets_deg) -> np.ndarray:
    """Distance (deg) of each relative phase from the nearest of 0 and 180 deg.

    Args:
        offsets_deg: relative phases (deg), any shape.

    Returns:
        Distances (deg, in [0, 90]), same shape as ``offsets_deg``.
    """
    off = np.abs(np.asarray(offsets_deg, dtype=float)) % 180.0
    return np.minimum(off, 180.0 - off)


def force_error(times_est, forces_est, times_meas, forces_meas, frequency: float | None = None) -> dict:
    """RMS of (estimated - measured) leg forces [n, 6] on the measured time base, absolute (N) and
    relative to the measured force amplitude (the fitted oscillation at ``frequency``, else half the
    peak-to-peak). Estimates are linearly interpolated to the measured stamps.

    Measured samples outside the estimate's time span are dropped.

    Args:
        times_est: increasing estimate times [m] (s).
        forces_est: estimated leg forces [m, 6] (N).
        times_meas: measurement times [n] (s).
        forces_meas: measured leg forces [n, 6] (N).
        frequency: vibration frequency (Hz) for the amplitude fit; None or 0: half the peak-to-peak.

    Returns:
        ``force_error_figures`` of the RMS errors and amplitudes, with "samples": the measured samples used.

    Raises:
        InvalidInputError: fewer than 4 measured samples lie within the estimate's time span, or (with
            ``frequency``) a measured force is not finite (``fit_sinusoid``).
    """
    te, fe = np.asarray(times_est, dtype=float), np.asarray(forces_est, dtype=float)
    tm, fm = np.asarray(times_meas, dtype=float), np.asarray(forces_meas, dtype=float)
    inside = (tm >= te[0]) & (tm <= te[-1])
    tm, fm = tm[inside], fm[inside]
    if tm.size < 4:
        raise InvalidInputError("force_error: the estimate and measurement do not overlap")
    est = np.stack([np.interp(tm, te, fe[:, k]) for k in range(fe.shape[1])], axis=1)
    diff = est - fm
    rms = np.sqrt((diff**2).mean(axis=0))
    if frequency:
        amplitude = fit_sinusoid(tm, fm, frequency).amplitude
    else:
        amplitude = (fm.max(axis=0) - fm.min(axis=0)) / 2
    return force_error_figures(rms, amplitude, int(tm.size))


def force_error_figures(rms_error_n, force_amplitude_n, samples: int) -> dict:
    """The leg-force error figures of per-leg RMS errors (6,) N and force amplitudes (6,) N: "rms_error_n",
    "force_amplitude_n", "relative_rms_error" (each leg's error over its own amplitude), "worst_leg_relative"
    (the largest of those) and "worst_leg_vs_largest_amplitude" (the largest error over the largest amplitude:
    the vibration's force scale), and "samples".

    A leg's own amplitude can be as small as its error, or zero: along some directions a leg's force hardly
    vibrates. The error against the force scale stays meaningful there, so it is the one a run is judged by.
    """
    rms, amplitude = np.asarray(rms_error_n, dtype=float), np.asarray(force_amplitude_n, dtype=float)
    relative = np.divide(rms, amplitude, out=np.full_like(rms, np.inf), where=amplitude > 0)
    scale = float(amplitude.max())
    return {"rms_error_n": rms, "force_amplitude_n": amplitude, "relative_rms_error": relative,
            "worst_leg_relative": float(relative.max()),
            "worst_leg_vs_largest_amplitude": float(rms.max() / scale) if scale > 0 else float("inf"),
            "samples": int(samples)}
