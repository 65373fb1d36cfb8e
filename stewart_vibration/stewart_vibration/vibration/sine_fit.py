"""Least-squares sinusoid fit at a known frequency (pure numpy): the complex amplitude of a sampled signal,
the demodulation both the run analysis and the vibration control use."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError


@dataclass(frozen=True)
class SinusoidFit:
    """x(t) ~ offset + amplitude sin(2 pi f t + phase) (+ drift t): per column [k]."""

    amplitude: np.ndarray
    phase: np.ndarray
    offset: np.ndarray
    complex_amplitude: np.ndarray  # c with x = Re(c exp(i(2 pi f t - pi/2))) = |c| sin(2 pi f t + arg c)
    residual_rms: np.ndarray


def fit_sinusoid(times, signals, frequency: float, drift: bool = True) -> SinusoidFit:
    """Fit columns of ``signals`` [n, k] (or [n]) at ``frequency`` (Hz) over ``times`` [n] (s).

    Least squares of x(t) ~ s sin(w t) + c cos(w t) + offset (+ drift (t - mean t)), w = 2 pi f,
    so amplitude = hypot(s, c) and phase = atan2(c, s).

    Args:
        times: sample times [n] (s).
        signals: samples [n, k] or [n] (any unit).
        frequency: the known frequency (Hz).
        drift: also fit a linear drift term.

    Returns:
        SinusoidFit; each field has the shape of ``signals`` without its first axis ([k], or 0-d for
        [n]): amplitude and offset (units of ``signals``), phase (rad, in [-pi, pi]), complex amplitude
        s + i c, residual_rms.

    Raises:
        InvalidInputError: fewer than 4 samples, or a non-finite value in ``signals``.
    """
    t = np.asarray(times, dtype=float)
    x = np.asarray(signals, dtype=float)
    x2 = x.reshape(t.size, -1)
    if t.size < 4 or not np.isfinite(x2).all():
        raise InvalidInputError("fit_sinusoid needs >= 4 finite samples")
    w = 2 * np.pi * frequency
    tc = t - t.mean()
    cols = [np.sin(w * t), np.cos(w * t), np.ones_like(t)] + ([tc] if drift else [])
    basis = np.stack(cols, axis=1)
    coef, *_ = np.linalg.lstsq(basis, x2, rcond=None)
    s, c = coef[0], coef[1]  # x = s sin + c cos = A sin(wt + phi), A cos phi = s, A sin phi = c
    resid = x2 - basis @ coef
    shape = x.shape[1:]
    return SinusoidFit(
        amplitude=np.hypot(s, c).reshape(shape),
        phase=np.arctan2(c, s).reshape(shape),
        offset=coef[2].reshape(shape),
        complex_amplitude=(s + 1j * c).reshape(shape),
        residual_rms=np.sqrt((resid**2).mean(axis=0)).reshape(shape),
    )
