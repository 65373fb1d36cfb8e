"""Splines (pure numpy): the Hermite interpolation of joint trajectories and vibration windows, and the
quintic smoothstep behind every ramp and minimum-jerk move.

As ros2_control's joint_trajectory_controller: between two knots a cubic segment when they carry
positions and velocities, a quintic one when they also carry accelerations. s in [0, 1] is the
normalised time within a segment of duration h (s); values broadcast over joints.
"""

from __future__ import annotations

import numpy as np


def smoothstep(x):
    """The quintic smoothstep s(x) = 10 x^3 - 15 x^4 + 6 x^5 and its first two derivatives.

    Zero velocity and acceleration at both ends: the minimum-jerk profile (Flash and Hogan 1985), the
    vibration's ramp envelope and the force guard's progress model all use it.

    Args:
        x: normalised time, any shape (clipped to [0, 1]).

    Returns:
        (s, ds/dx, d2s/dx2), each of the shape of ``x``.
    """
    x = np.clip(np.asarray(x, dtype=float), 0.0, 1.0)
    value = x**3 * (10.0 + x * (-15.0 + 6.0 * x))
    first = 30.0 * x**2 * (1.0 - x) ** 2
    second = 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x)
    return value, first, second


def smoothstep_integral(x):
    """S(x) = the integral of ``smoothstep`` from 0 to x: 2.5 x^4 - 3 x^5 + x^6 on [0, 1], 0 below, x - 1/2
    above (the smoothstep is 1 there).

    Args:
        x: normalised time, any shape.

    Returns:
        S(x), the shape of ``x``.
    """
    x = np.asarray(x, dtype=float)
    c = np.clip(x, 0.0, 1.0)
    return np.where(x > 1.0, x - 0.5, c**4 * (2.5 + c * (-3.0 + c)))


def quintic_hermite(s, h, p0, v0, a0, p1, v1, a1):
    """Quintic Hermite on s in [0, 1] over duration h -> (p, v, a)."""
    s2, s3, s4, s5 = s * s, s**3, s**4, s**5
    p = (
        (1 - 10 * s3 + 15 * s4 - 6 * s5) * p0
        + (s - 6 * s3 + 8 * s4 - 3 * s5) * h * v0
        + (0.5 * s2 - 1.5 * s3 + 1.5 * s4 - 0.5 * s5) * h * h * a0
        + (10 * s3 - 15 * s4 + 6 * s5) * p1
        + (-4 * s3 + 7 * s4 - 3 * s5) * h * v1
        + (0.5 * s3 - s4 + 0.5 * s5) * h * h * a1
    )
    dp = (-30 * s2 + 60 * s3 - 30 * s4) * (p0 - p1) / h
    v = (
        dp
        + (1 - 18 * s2 + 32 * s3 - 15 * s4) * v0
        + (s - 4.5 * s2 + 6 * s3 - 2.5 * s4) * h * a0
        + (-12 * s2 + 28 * s3 - 15 * s4) * v1
        + (1.5 * s2 - 4 * s3 + 2.5 * s4) * h * a1
    )
    a = (
        (-60 * s + 180 * s2 - 120 * s3) * (p0 - p1) / h**2
        + (-36 * s + 96 * s2 - 60 * s3) * v0 / h
        + (1 - 9 * s + 18 * s2 - 10 * s3) * a0
        + (-24 * s + 84 * s2 - 60 * s3) * v1 / h
        + (3 * s - 12 * s2 + 10 * s3) * a1
    )
    return p, v, a


def cubic_hermite(s, h, p0, v0, p1, v1):
    """Cubic Hermite on s in [0, 1] over duration h -> (p, v, a)."""
    s2, s3 = s * s, s**3
    p = (2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * h * v0 + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * h * v1
    v = (6 * s2 - 6 * s) * (p0 - p1) / h + (3 * s2 - 4 * s + 1) * v0 + (3 * s2 - 2 * s) * v1
    a = (12 * s - 6) * (p0 - p1) / h**2 + (6 * s - 4) * v0 / h + (6 * s - 2) * v1 / h
    return p, v, a


def spline_segments(knot_times, positions, velocities, accelerations, times, segments=None):
    """(p, v, a) [m, k] of the Hermite spline through the knots at ``times`` [m] within
    [knot_times[0], knot_times[-1]]: per segment cubic (positions + velocities), or quintic when
    both of its knots carry accelerations (``accelerations`` [n, k] with NaN rows where a knot has
    none; None = none at all), as joint_trajectory_controller interpolates. ``segments`` [m]: the
    segment of each time (default: the one it falls in; a time on a knot starts the next segment)."""
    kt = knot_times
    seg = np.clip(np.searchsorted(kt, times, side="right") - 1, 0, kt.size - 2) if segments is None \
        else np.asarray(segments)
    h = (kt[seg + 1] - kt[seg])[:, None]
    s = (times - kt[seg])[:, None] / h
    p0, v0, p1, v1 = positions[seg], velocities[seg], positions[seg + 1], velocities[seg + 1]
    if accelerations is None:
        return cubic_hermite(s, h, p0, v0, p1, v1)
    a0, a1 = accelerations[seg], accelerations[seg + 1]
    quintic = ~(np.isnan(a0[:, 0]) | np.isnan(a1[:, 0]))
    if quintic.all():
        return quintic_hermite(s, h, p0, v0, a0, p1, v1, a1)
    out = cubic_hermite(s, h, p0, v0, p1, v1)
    if quintic.any():
        q = quintic
        quin = quintic_hermite(s[q], h[q], p0[q], v0[q], a0[q], p1[q], v1[q], a1[q])
        for full, part in zip(out, quin, strict=True):
            full[q] = part
    return out


SAMPLES_PER_SEGMENT = 4  # extremes: each segment's ends and this many points inside ...
REFINED_SAMPLES = 64  # ... and this many in segments that come within NEAR_LIMIT of a bound
NEAR_LIMIT = 0.9


# Hermite basis polynomials in s (ascending coefficients) of the terms p0, h v0, h^2 a0, p1, h v1, h^2 a1: the
# same curves as ``quintic_hermite`` and ``cubic_hermite`` (the cubic has no acceleration terms)
_QUINTIC_BASIS = np.array([
    [1, 0, 0, -10, 15, -6],
    [0, 1, 0, -6, 8, -3],
    [0, 0, 0.5, -1.5, 1.5, -0.5],
    [0, 0, 0, 10, -15, 6],
    [0, 0, 0, -4, 7, -3],
    [0, 0, 0, 0.5, -1, 0.5],
])
_CUBIC_BASIS = np.array([
    [1, 0, -3, 2, 0, 0],
    [0, 1, -2, 1, 0, 0],
    [0, 0, 0, 0, 0, 0],
    [0, 0, 3, -2, 0, 0],
    [0, 0, -1, 1, 0, 0],
    [0, 0, 0, 0, 0, 0],
])


def _basis_at(basis: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The six basis terms and their first two derivatives in s, each [len(s), 6]."""
    P = np.polynomial.polynomial

    def terms(order: int) -> np.ndarray:
        return np.stack([P.polyval(s, P.polyder(row, order)) for row in basis], axis=1)

    return terms(0), terms(1), terms(2)


def _segment_extremes(knot_times, positions, velocities, accelerations, samples: int, segments):
    """Per segment [m, k]: min and max position, max |velocity|, max |acceleration| over its ends and
    ``samples`` points inside (the same points in every segment's normalised time, so the basis is evaluated once
    and each segment is a weighted sum of its six knot terms)."""
    seg = np.asarray(segments)
    s = np.arange(samples + 2) / (samples + 1)
    h = knot_times[seg + 1] - knot_times[seg]
    hh = h[:, None]
    p0, v0, p1, v1 = positions[seg], velocities[seg], positions[seg + 1], velocities[seg + 1]
    if accelerations is None:
        a0 = a1 = np.zeros_like(p0)
        quintic = np.zeros(len(seg), dtype=bool)
    else:
        a0, a1 = accelerations[seg], accelerations[seg + 1]
        quintic = ~(np.isnan(a0[:, 0]) | np.isnan(a1[:, 0]))
        a0, a1 = np.where(quintic[:, None], a0, 0.0), np.where(quintic[:, None], a1, 0.0)
    terms = np.stack([p0, hh * v0, hh * hh * a0, p1, hh * v1, hh * hh * a1])  # [6, m, k]
    lo, hi, vmax, amax = (np.empty_like(p0) for _ in range(4))
    for basis, rows in ((_QUINTIC_BASIS, quintic), (_CUBIC_BASIS, ~quintic)):
        if rows.any():
            bp, bv, ba = _basis_at(basis, s)
            t = terms[:, rows].reshape(6, -1)  # one matrix product per quantity: [points, 6] @ [6, segments * k]
            shape = (s.size, int(rows.sum()), p0.shape[1])
            p = (bp @ t).reshape(shape)
            lo[rows], hi[rows] = p.min(axis=0), p.max(axis=0)
            vmax[rows] = np.abs((bv @ t).reshape(shape)).max(axis=0) / h[rows, None]
            amax[rows] = np.abs((ba @ t).reshape(shape)).max(axis=0) / h[rows, None] ** 2
    return lo, hi, vmax, amax


def spline_extremes(knot_times, positions, velocities, accelerations=None, *, position_bounds=None,
                    velocity_bound=None, acceleration_bound=None):
    """(min position, max position, max |velocity|, max |acceleration|), each [k], of the Hermite spline
    through the knots (see ``spline_segments``), evaluated at each segment's ends and
    SAMPLES_PER_SEGMENT points inside, and at REFINED_SAMPLES points in segments that come within
    NEAR_LIMIT of a given bound (position_bounds = (low, high), velocity_bound, acceleration_bound;
    scalars or [k]); between those points a smooth segment exceeds the sampled extreme by at most
    (h / REFINED_SAMPLES)^2 times its curvature. One knot: its own values (acceleration 0 if none)."""
    t = np.asarray(knot_times, float)
    pos, vel = np.asarray(positions, float), np.asarray(velocities, float)
    acc = None if accelerations is None else np.asarray(accelerations, float)
    if len(t) < 2:
        a = np.zeros(pos.shape[1]) if acc is None or np.isnan(acc).any() else np.abs(acc[0])
        return pos[0].copy(), pos[0].copy(), np.abs(vel[0]), a
    lo, hi, vmax, amax = _segment_extremes(t, pos, vel, acc, SAMPLES_PER_SEGMENT, np.arange(len(t) - 1))
    near = np.zeros(len(lo), dtype=bool)
    if position_bounds is not None:
        low, high = position_bounds
        span = np.asarray(high, float) - np.asarray(low, float)
        margin = (1 - NEAR_LIMIT) * span
        near |= ((lo < low + margin) | (hi > high - margin)).any(axis=1)
    if velocity_bound is not None:
        near |= (vmax > NEAR_LIMIT * np.asarray(velocity_bound)).any(axis=1)
    if acceleration_bound is not None:
        near |= (amax > NEAR_LIMIT * np.asarray(acceleration_bound)).any(axis=1)
    if near.any():
        refined = _segment_extremes(t, pos, vel, acc, REFINED_SAMPLES, np.flatnonzero(near))
        for table, values in zip((lo, hi, vmax, amax), refined, strict=True):
            table[near] = values
    return lo.min(axis=0), hi.max(axis=0), vmax.max(axis=0), amax.max(axis=0)
