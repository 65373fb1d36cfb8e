"""The scalar vibration delta(t) = e(t) A sin(2 pi f t + phase) with a smooth envelope.

Times are relative to the vibration start (the planner's common start
stamp). The envelope e(t) ramps in over ``ramp_time`` from t = 0 and out over
``ramp_time`` before t = ``duration`` with the quintic smoothstep
10x^3 - 15x^4 + 6x^5, whose first and second derivatives vanish at both
ends, so displacement, velocity and acceleration are continuous.
"""

from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError
from ..robot import STANDARD_GRAVITY
from ..splines import smoothstep


def envelope(times, duration: float | None = None, ramp_time: float = 0.0):
    """Envelope e(t), de/dt (1/s), d2e/dt2 (1/s^2) for times [N] (s from the start).

    e = 0 before t = 0 and (with a duration) after t = duration; ramps of
    ``ramp_time`` seconds at both ends (0: a hard start/stop, e = 1 inside).

    Args:
        times: times [N] (s from the vibration start).
        duration: end of the vibration (s), or None for no end.
        ramp_time: length of each quintic ramp (s, >= 0).

    Returns:
        (e, de/dt (1/s), d2e/dt2 (1/s^2)), each of the shape of ``times``.

    Raises:
        InvalidInputError: ``ramp_time`` is negative or not finite, or two ramps do not fit in ``duration``.
    """
    t = np.asarray(times, dtype=float)
    if ramp_time < 0 or not np.isfinite(ramp_time):
        raise InvalidInputError(f"ramp_time must be >= 0 s, got {ramp_time}")
    if duration is not None and ramp_time > 0 and 2 * ramp_time > duration:
        raise InvalidInputError(f"ramp_time {ramp_time} s: two ramps do not fit in duration {duration} s")
    inside = t >= 0.0
    if duration is not None:
        inside &= t <= duration
    value = inside.astype(float)
    first = np.zeros_like(t)
    second = np.zeros_like(t)
    if ramp_time > 0:
        s, ds, dds = smoothstep(t / ramp_time)
        value = np.where(inside, s, 0.0)
        first = np.where(inside, ds / ramp_time, 0.0)
        second = np.where(inside, dds / ramp_time**2, 0.0)
        if duration is not None:
            s2, ds2, dds2 = smoothstep((duration - t) / ramp_time)
            # product rule e = s(t) s2(t); ramps do not overlap, but the product is exact anyway
            value, first, second = (
                value * s2,
                first * s2 - value * ds2 / ramp_time,
                second * s2 - 2.0 * first * ds2 / ramp_time + value * dds2 / ramp_time**2,
            )
            value = np.where(inside, value, 0.0)
    return value, first, second


def product_rule(f, g):
    """(f g, (f g)', (f g)'') from (f, f', f'') and (g, g', g'') (arrays that broadcast).

    Args:
        f: (f, f', f'').
        g: (g, g', g'').

    Returns:
        (f g, f' g + f g', f'' g + 2 f' g' + f g''), broadcast.
    """
    f0, f1, f2 = f
    g0, g1, g2 = g
    return f0 * g0, f1 * g0 + f0 * g1, f2 * g0 + 2.0 * f1 * g1 + f0 * g2


def fade_out(times, start: float, ramp_time: float):
    """Falling envelope g(t), dg/dt, d2g/dt2 [N]: 1 before ``start``, a quintic smoothstep to 0 over
    ``ramp_time`` (s), 0 after. Times and start in the same time base (s).

    Args:
        times: times [N] (s).
        start: time the fade starts (s).
        ramp_time: length of the fade (s, >= 0; 0: a hard stop after ``start``).

    Returns:
        (g, dg/dt (1/s), d2g/dt2 (1/s^2)), each [N].

    Raises:
        InvalidInputError: ``ramp_time`` is negative or not finite (``envelope``).
    """
    g, rate, curve = envelope(start + ramp_time - np.asarray(times, dtype=float), None, ramp_time)
    return g, -rate, curve


def sinusoid(times, amplitude: float, frequency: float, phase: float, duration=None, ramp_time: float = 0.0,
             fade=None):
    """delta, d delta/dt, d2 delta/dt2 [N] of e(t) A sin(2 pi f t + phase) (units of A per s^k).

    Args:
        times: times [N] (s from the vibration start).
        amplitude: A (m for a translation, rad for a rotation).
        frequency: f (Hz).
        phase: phase (rad).
        duration: end of the vibration (s), or None for no end (``envelope``).
        ramp_time: length of the ramp-in and ramp-out (s, >= 0).
        fade: an optional extra envelope (g, g', g'') [N] multiplied onto e(t) (e.g. ``fade_out``).

    Returns:
        (delta, d delta/dt, d2 delta/dt2), each [N] (units of A, A/s, A/s^2).

    Raises:
        InvalidInputError: ``ramp_time`` is negative or not finite, or two ramps do not fit in ``duration``.
    """
    t = np.asarray(times, dtype=float)
    omega = 2.0 * np.pi * frequency
    angle = omega * t + phase
    s, c = np.sin(angle), np.cos(angle)
    e, de, dde = envelope(t, duration, ramp_time)
    if fade is not None:
        e, de, dde = product_rule((e, de, dde), fade)
    delta = amplitude * e * s
    velocity = amplitude * (de * s + e * omega * c)
    acceleration = amplitude * (dde * s + 2.0 * de * omega * c - e * omega**2 * s)
    return delta, velocity, acceleration


def default_times(frequency: float, duration: float | None = None, samples_per_period: int = 256) -> np.ndarray:
    """Uniform sample times (s): one period of ``frequency`` (endpoint excluded) or ``duration``.

    Args:
        frequency: f (Hz, > 0).
        duration: time span (s), or None for one period.
        samples_per_period: samples per period (>= 8); the step is 1 / (f samples_per_period).

    Returns:
        Times [samples_per_period] (s) over one period, or [M] from 0 up to ``duration`` (s;
        ``duration`` included when it falls on the step).

    Raises:
        InvalidInputError: ``samples_per_period`` < 8, or ``duration`` <= 0.
    """
    if samples_per_period < 8:
        raise InvalidInputError("samples_per_period must be >= 8")
    step = 1.0 / (frequency * samples_per_period)
    if duration is None:
        return np.arange(samples_per_period) * step
    if duration <= 0:
        raise InvalidInputError(f"duration must be > 0 s, got {duration}")
    return np.arange(int(np.floor(duration / step + 1e-9)) + 1) * step


def displacement_from_acceleration(acceleration_g: float, frequency: float) -> float:
    """Peak displacement X = a / (2 pi f)^2 (m) of a sinusoid with peak acceleration a (g) at f (Hz).

    Args:
        acceleration_g: peak acceleration a (g, standard gravities).
        frequency: f (Hz, non-zero).

    Returns:
        X (m).
    """
    return float(acceleration_g) * STANDARD_GRAVITY / (2.0 * np.pi * float(frequency)) ** 2


def acceleration_from_displacement(amplitude: float, frequency: float) -> float:
    """Peak acceleration (g) of a sinusoid of peak displacement ``amplitude`` (m) at f (Hz).

    Args:
        amplitude: peak displacement X (m).
        frequency: f (Hz).

    Returns:
        X (2 pi f)^2 in g (standard gravities).
    """
    return float(amplitude) * (2.0 * np.pi * float(frequency)) ** 2 / STANDARD_GRAVITY
