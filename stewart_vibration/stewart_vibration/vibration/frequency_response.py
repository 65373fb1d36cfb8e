"""Frequency responses from stepped-sine records (pure numpy): how each output answers one sinusoidal input at
the input's frequency.

The record is cut into blocks of whole periods; in each block the input and every output are demodulated at
the known frequency (a least-squares sinusoid fit with offset and drift: vibration.sine_fit), giving complex
amplitudes D_b and Y_b (x = |c| sin(2 pi f t + arg c)). Then, as the H1 estimator of a swept-sine test:

    H = sum_b conj(D_b) Y_b / sum_b |D_b|^2
    coherence = |sum_b conj(D_b) Y_b|^2 / (sum_b |D_b|^2 sum_b |Y_b|^2)     (1: the output follows the input)
    uncertainty = std_b(Y_b / D_b) / sqrt(B)                                (standard error of H)

Noise uncorrelated with the input spreads Y_b from block to block: the coherence falls below 1 and the
uncertainty grows, which is how a poor identification is recognised.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError
from .sine_fit import fit_sinusoid


@dataclass(frozen=True)
class SineResponse:
    """The response of k outputs to one input at one frequency.

    response (k,) complex: output amplitude per input amplitude (output unit per input unit) and phase lead
    (rad, arg); coherence (k,) in [0, 1]; uncertainty (k,): standard error of ``response`` (same unit);
    blocks: how many blocks of whole periods were averaged.
    """

    response: np.ndarray
    coherence: np.ndarray
    uncertainty: np.ndarray
    blocks: int


def block_bounds(times: np.ndarray, frequency: float, blocks: int) -> list[tuple[int, int]]:
    """Index ranges [start, stop) of ``blocks`` consecutive blocks of whole periods of ``frequency`` (Hz) in
    ``times`` (s, increasing); InvalidInputError when the record holds fewer than one period per block."""
    periods = int(np.floor((times[-1] - times[0]) * frequency + 1e-9))
    per_block = periods // blocks
    if per_block < 1:
        raise InvalidInputError(f"a record of {times[-1] - times[0]:.4g} s holds {periods} periods of "
                                f"{frequency:g} Hz: fewer than one per block ({blocks} blocks)")
    edges = times[0] + np.arange(blocks + 1) * per_block / frequency
    index = np.searchsorted(times, edges - 1e-9)
    return [(int(a), int(b)) for a, b in zip(index[:-1], index[1:])]


def sine_response(times, demand, outputs, frequency: float, blocks: int = 4) -> SineResponse:
    """H1 response of ``outputs`` (n, k) to ``demand`` (n,) at ``frequency`` (Hz) over ``times`` (n,, s).

    Raises:
        InvalidInputError: shapes disagree, a value is not finite, too few periods for ``blocks``, or the
            demand has no component at ``frequency``.
    """
    t = np.asarray(times, dtype=float)
    d = np.asarray(demand, dtype=float)
    y = np.asarray(outputs, dtype=float)
    y = y[:, None] if y.ndim == 1 else y
    if t.ndim != 1 or d.shape != t.shape or y.shape[0] != t.size or blocks < 2:
        raise InvalidInputError("sine_response needs times (n,), demand (n,), outputs (n, k) and >= 2 blocks")
    if not (np.isfinite(t).all() and np.isfinite(d).all() and np.isfinite(y).all()):
        raise InvalidInputError("sine_response: a sample is not finite")
    fits_d, fits_y = [], []
    for a, b in block_bounds(t, frequency, blocks):
        both = fit_sinusoid(t[a:b], np.column_stack([d[a:b], y[a:b]]), frequency)
        fits_d.append(both.complex_amplitude[0])
        fits_y.append(both.complex_amplitude[1:])
    d_b, y_b = np.asarray(fits_d), np.asarray(fits_y)  # (B,), (B, k)
    sxx = float(np.sum(np.abs(d_b) ** 2))
    peak = np.sqrt(2.0) * float(np.std(d))  # a pure sine's amplitude
    if sxx <= 0.0 or np.min(np.abs(d_b)) < 0.5 * peak:
        raise InvalidInputError(f"the demand is not a sine at {frequency:g} Hz in every block (its component "
                                f"there {np.min(np.abs(d_b)):.3g} of an amplitude {peak:.3g}): a stepped sine "
                                "holds one frequency at a time")
    sxy = np.sum(np.conj(d_b)[:, None] * y_b, axis=0)
    syy = np.sum(np.abs(y_b) ** 2, axis=0)
    response = sxy / sxx
    with np.errstate(invalid="ignore", divide="ignore"):
        coherence = np.where(syy > 0.0, np.abs(sxy) ** 2 / (sxx * syy), 1.0)  # an exact zero output: explained
    per_block = y_b / d_b[:, None]
    uncertainty = np.sqrt(np.sum(np.abs(per_block - response) ** 2, axis=0) / (len(d_b) - 1) / len(d_b))
    return SineResponse(response, np.clip(coherence, 0.0, 1.0), uncertainty, len(d_b))


def platform_motion_response(accel_response, gyro_response, frequency: float, rotation, gravity=(0.0, 0.0, 0.0),
                             accel_average_s: float = 0.0) -> np.ndarray:
    """The platform's 6-DOF motion response (6,) complex [dp (m); dphi (rad)], base frame, from the responses
    of an IMU at the platform origin: specific force (3,) complex (m/s^2 per input unit) and angular rate (3,)
    complex (rad/s per input unit), platform-frame axes; ``rotation`` (3, 3) the platform's (nominal)
    orientation and ``gravity`` (3,) m/s^2 in the base frame (the robot's).

    At the input's frequency w = 2 pi f a displacement c has the acceleration -w^2 c and a rotation c the
    rate i w c (x = Im(c exp(i w t))). The accelerometer reads R^T (a - g); turned by the small rotation
    dphi its oscillating part is R0^T (a + dphi x g), so a = R0 f - dphi x g (a unit driven alone rocks the
    platform: that term is a few per cent there). An accelerometer that reports the mean specific force over
    the ``accel_average_s`` (s) before each sample (integrate and dump over its sample period) shows
    exp(-i w T/2) sin(w T/2) / (w T/2) of it: divided out here (at 35 Hz and 2 ms, 12.6 deg of lag).
    """
    w = 2.0 * np.pi * float(frequency)
    rot = np.asarray(rotation, dtype=float)
    half = 0.5 * w * float(accel_average_s)
    average = np.exp(-1j * half) * (np.sin(half) / half if half > 0 else 1.0)
    dphi = rot @ (np.asarray(gyro_response, dtype=complex) / (1j * w))
    g = np.asarray(gravity, dtype=float).reshape((3,) + (1,) * (dphi.ndim - 1))
    acceleration = rot @ (np.asarray(accel_response, dtype=complex) / average) - np.cross(dphi, g, axis=0)
    return np.concatenate([acceleration / (-w * w), dphi])


def platform_motion(times, accel, gyro, frequency: float, rotation, gravity=(0.0, 0.0, 0.0),
                    accel_average_s: float = 0.0) -> np.ndarray:
    """The platform's 6-DOF motion (6,) complex [dp (m); dphi (rad)], base frame, at ``frequency`` (Hz) over
    IMU samples at ``times`` (N,) s from the vibration's t0: its complex amplitude against the carrier
    sin(2 pi f t) (the same reference as the legs' demands), by synchronous demodulation (a least-squares
    fit at the frequency, with offset and drift: the IMU's biases and gravity drop out); ``accel`` (N, 3)
    m/s^2, ``gyro`` (N, 3) rad/s, platform frame; the rest as ``platform_motion_response``. Use whole periods.
    """
    fit = fit_sinusoid(times, np.column_stack([np.asarray(accel, float), np.asarray(gyro, float)]), frequency)
    c = fit.complex_amplitude
    return platform_motion_response(c[:3], c[3:], frequency, rotation, gravity, accel_average_s)
