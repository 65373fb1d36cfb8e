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


class SineSums:
    """``fit_sinusoid`` (with its drift term) over samples that arrive in batches and are not held: the normal
    equations of its least squares, summed batch by batch. ``fit()`` is fit_sinusoid of every sample added, to
    rounding, in any batches and any order.

    The drift column is (t - middle) / half-length of ``span`` (s), the same column space as fit_sinusoid's
    t - mean(t) (so the same sine, cosine and residual; the offset is reported at the samples' mean time, as
    there), and better conditioned over an hour. Each column is summed relative to its first sample: the residual
    is then not the difference of two large numbers.
    """

    def __init__(self, frequency: float, width: int, span: tuple[float, float]):
        self.omega = 2 * np.pi * float(frequency)
        self.middle, self.scale = 0.5 * (span[0] + span[1]), max(0.5 * (span[1] - span[0]), 1e-9)
        self.gram, self.moments = np.zeros((4, 4)), np.zeros((4, width))
        self.squares, self.reference = np.zeros(width), None
        self.count, self.time_sum, self.not_finite = 0, 0.0, 0

    def _basis(self, t: np.ndarray) -> np.ndarray:
        return np.stack([np.sin(self.omega * t), np.cos(self.omega * t), np.ones_like(t),
                         (t - self.middle) / self.scale], axis=1)

    def add(self, times, signals) -> None:
        """Samples: times [n] (s), signals [n, width]; a batch with a non-finite value is counted, not summed
        (``fit`` then refuses, as fit_sinusoid does)."""
        t = np.asarray(times, dtype=float)
        if not t.size:
            return
        x = np.asarray(signals, dtype=float).reshape(t.size, -1)
        if not np.isfinite(x).all():
            self.not_finite += int(np.count_nonzero(~np.isfinite(x)))
            return
        if self.reference is None:
            self.reference = x[0].copy()
        y = x - self.reference
        basis = self._basis(t)
        self.gram += basis.T @ basis
        self.moments += basis.T @ y
        self.squares += (y * y).sum(axis=0)
        self.count += t.size
        self.time_sum += float(t.sum())

    def merged(self, other: SineSums) -> SineSums:
        """The sums of both (the same frequency, width and span): a new SineSums."""
        out = SineSums(self.omega / (2 * np.pi), self.moments.shape[1], (self.middle - self.scale,
                                                                         self.middle + self.scale))
        for part in (self, other):
            if part.reference is None:
                continue
            if out.reference is None:
                out.reference = part.reference.copy()
            shift = part.reference - out.reference  # re-reference: y' = y + shift
            column = part.gram[:, 2]  # basis' 1 (the sums of each basis column)
            out.gram += part.gram
            out.moments += part.moments + np.outer(column, shift)
            out.squares += part.squares + 2 * shift * part.moments[2] + part.count * shift**2
            out.count += part.count
            out.time_sum += part.time_sum
        out.not_finite = self.not_finite + other.not_finite
        return out

    def fit(self) -> SinusoidFit:
        """The fit of every sample added (fields [width], as fit_sinusoid's of [n, width] signals).

        Raises:
            InvalidInputError: fewer than 4 samples, or a non-finite value was added.
        """
        if self.count < 4 or self.not_finite:
            raise InvalidInputError("fit_sinusoid needs >= 4 finite samples")
        coef = np.linalg.lstsq(self.gram, self.moments, rcond=None)[0]
        s, c = coef[0], coef[1]
        residual = self.squares - (coef * self.moments).sum(axis=0)  # y'y - b'B'y at the least-squares b
        mean_t = self.time_sum / self.count
        offset = self.reference + coef[2] + coef[3] * (mean_t - self.middle) / self.scale
        return SinusoidFit(amplitude=np.hypot(s, c), phase=np.arctan2(c, s), offset=offset,
                           complex_amplitude=s + 1j * c, residual_rms=np.sqrt(np.maximum(residual, 0.0) / self.count))
