"""Leg vibration demands as complex amplitudes (pure numpy): the feed-forward of identified units, and the
samples of demands that change smoothly from one set to another (a closed-loop correction spliced into a
streamed vibration without a step in position, velocity or acceleration).

A leg's demand u_i (complex, m) means vib_i(t) = e(t) |u_i| sin(2 pi f t + arg u_i), e(t) the vibration's
envelope (its ramps). The decomposition's first-order legs are u_i = k_i A exp(i phase)
(``decomposition_demands``); a unit that answers its demand with the complex response H_i delivers H_i u_i,
so the feed-forward demand is u_i / H_i (``feedforward_demands``).
"""

from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError
from ..splines import smoothstep
from .decompose import VibrationDecomposition
from .waveform import product_rule


def decomposition_demands(plan: VibrationDecomposition) -> np.ndarray:
    """The decomposition's first-order leg demands (6,) complex m: k_i A exp(i phase)."""
    return np.asarray(plan.gains, dtype=float) * plan.amplitude * np.exp(1j * plan.phase)


def feedforward_demands(demands, unit_response) -> np.ndarray:
    """Demands (6,) complex divided by each unit's identified response (6,) complex at the frequency.

    Raises:
        InvalidInputError: a response that is not finite or too small to divide by (a dead unit).
    """
    h = np.asarray(unit_response, dtype=complex).reshape(6)
    if not np.isfinite(h).all() or np.min(np.abs(h)) < 0.05:
        raise InvalidInputError(f"unit responses {np.round(np.abs(h), 3).tolist()}: a unit answering with less "
                                "than 5 % of its demand cannot be compensated (identify again, or the unit failed)")
    return np.asarray(demands, dtype=complex).reshape(6) / h


def blended_demand_samples(times, frequency: float, before, after, blend_start: float, blend_time: float,
                           envelope) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, velocity and acceleration (N, 6) of demands that go from ``before`` to ``after`` (6,)
    complex over ``blend_time`` s from ``blend_start`` (s, the times' clock) along a quintic smoothstep,
    under ``envelope`` (e, e', e'') (N,) each (``waveform.envelope``, with any fade).

    x = e Im(c z), z = exp(i w t), c(t) = before + (after - before) s((t - blend_start) / blend_time): smooth
    to the second derivative everywhere, equal to the ``before`` demands until the blend and to ``after``
    from its end, so a window that starts at or before ``blend_start`` splices onto one sampled with
    ``before`` alone.
    """
    t = np.asarray(times, dtype=float)
    if blend_time <= 0 or not np.isfinite(blend_time):
        raise InvalidInputError(f"blend_time must be > 0 s, got {blend_time!r}")
    u0 = np.asarray(before, dtype=complex).reshape(1, 6)
    du = np.asarray(after, dtype=complex).reshape(1, 6) - u0
    s, ds, dds = smoothstep((t - blend_start) / blend_time)
    c = u0 + du * s[:, None]
    c1 = du * (ds / blend_time)[:, None]
    c2 = du * (dds / blend_time**2)[:, None]
    w = 2.0 * np.pi * frequency
    z = np.exp(1j * w * t)[:, None]
    carrier = (c * z, (c1 + 1j * w * c) * z, (c2 + 2j * w * c1 - w * w * c) * z)  # d^k/dt^k of c z
    e, de, dde = (np.asarray(x, dtype=float)[:, None] for x in envelope)
    x, v, a = product_rule((e, de, dde), tuple(np.imag(k) for k in carrier))
    return x, v, a
