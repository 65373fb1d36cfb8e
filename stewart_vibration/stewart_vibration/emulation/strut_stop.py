"""Stopping the struts within their limits (pure numpy): the controlled stop that every safety stop commands
(e-stop, lifecycle deactivate, shutdown), and the stop reserve that every accepted strut command must leave.

The stop follows the commanded path, slowed down. From the stop time t0 the follower's command c(t) is
sampled at a warped time sigma(t) = t0 + tau - T S(tau / T), tau = t - t0 (S: ``splines.smoothstep_integral``),
so the path's speed factor sigma' = 1 - s(tau / T) falls from 1 to 0 along the quintic smoothstep over T and
the struts come to rest at c(t0 + T / 2):

    l(t) = c(sigma),  l' = c'(sigma) sigma',  l'' = c''(sigma) sigma'^2 + c'(sigma) sigma''.

Every length the stop passes is one the accepted command passes, so the stop stays inside the stroke and
the workspace checked when the command was accepted -- it never makes an end point of its own (the old
quintic stop ran up to 0.54 mm past the stroke end near it). Its velocity stays within the command's
(sigma' <= 1); its acceleration starts at the commanded one (sigma'' = 0 at t0: no step) and ends at 0.
``controlled_stop`` picks the shortest T on a grid whose sampled acceleration stays within
strut_acceleration_max.

Where the command brakes so hard that no slowed-down version of it fits, and it comes to rest by itself
(its last point) within STOP_MAX_S, the stop is the command itself: it follows the accepted plan to its end.

The stop reserve. With sigma' <= 1 and |sigma''| <= 1.875 / T, |l''_i| <= max(|c''_i|, B_i + |c'_i| 1.875 / T),
B_i = max(0, -c''_i sign c'_i) being how hard strut i brakes already. A command accepted by the emulator keeps
B_i + |c'_i| 1.875 / STOP_RESERVE_S within strut_acceleration_max at every sample that lies more than
STOP_RESERVE_S before its end (``check_stop_reserve``; in its last STOP_RESERVE_S the command itself is a stop
within the limits), so a stop of at most STOP_RESERVE_S exists from every instant of it; at full speed a
command may brake at up to 81 % of the acceleration limit, at half speed at up to 91 %, and at the limit
itself in its last STOP_RESERVE_S (the force guard's stops, the end of a move).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ActuatorLimitError
from ..splines import smoothstep, smoothstep_integral

STOP_RESERVE_S = 2.0  # every accepted command can be stopped within this time (s)
STOP_MAX_S = 4 * STOP_RESERVE_S  # the longest stop tried (s)
STOP_MIN_S = 0.05  # the shortest stop tried (s)
STOP_GRID = 1.15  # ratio between the stop durations tried
STOP_SAMPLES = 160  # samples of each tried stop
STOP_REFINE = 8  # durations tried between the last too short one and the first that fits
STOP_MARGIN = 0.98  # a stop is taken at this fraction of the acceleration limit on its samples (between them it may
# rise a little) -- or, if none does, at the limit itself
PEAK_SPEED = 1.875  # max of the smoothstep's derivative (the peak of -sigma'' T)
RESERVE_SUBGRID_S = 0.01  # stop-reserve samples at least this often (s), plus every knot and 4 points per segment
AT_REST = 1e-9  # m/s and m/s^2: a commanded state this slow needs no stop


@dataclass(frozen=True)
class StrutStop:
    """A controlled stop from ``at`` (s, absolute) over ``duration`` (s): the command is followed at the
    warped time ``warp`` gives; at rest from ``at + duration`` on."""

    at: float
    duration: float
    follows_plan: bool = False  # the command itself to its end (no warp)

    @property
    def end(self) -> float:
        """When the struts are at rest (s)."""
        return self.at + self.duration

    def warp(self, times):
        """(sigma [n] (s, absolute), sigma' [n], sigma'' [n] (1/s)) at absolute times [n] >= ``at``."""
        if self.follows_plan:
            times = np.asarray(times, dtype=float)
            return times, np.ones_like(times), np.zeros_like(times)
        tau = np.asarray(times, dtype=float) - self.at
        x = tau / self.duration
        ease, rate, _ = smoothstep(x)
        sigma = self.at + tau - self.duration * smoothstep_integral(x)
        return sigma, 1.0 - ease, -rate / self.duration


def braked(stop: StrutStop, sample, times):
    """The stopped command (positions, velocities, accelerations) [n, dof] at absolute times [n] >= stop.at,
    from ``sample`` (times [n] -> the unstopped command's (p, v, a))."""
    sigma, rate, curve = stop.warp(times)
    p, v, a = sample(sigma)
    return p, v * rate[:, None], a * (rate * rate)[:, None] + v * curve[:, None]


def controlled_stop(follower, at: float, acceleration_max: float) -> StrutStop | None:
    """The stop a safety stop commands at ``at`` (s) from the follower's commanded motion (see the module
    docstring): the shortest duration on the STOP_GRID grid from STOP_MIN_S (and at least 1.875 |v0| /
    (STOP_MARGIN acceleration_max)) to STOP_MAX_S whose sampled acceleration stays within STOP_MARGIN of
    ``acceleration_max`` (m/s^2); else the plan itself if it comes to rest within STOP_MAX_S; else the
    shortest within the limit itself, else the one with the smallest peak.

    Args:
        follower: the strut follower (``sample(times) -> (p, v, a)``, ``rest_time()``) whose command is stopped;
            a command still waiting for its start must be dropped first (``TrajectoryFollower.brake`` does).
        at: the stop time (s, absolute).
        acceleration_max: strut_acceleration_max (m/s^2).

    Returns:
        The StrutStop, or None when the commanded state at ``at`` is at rest (nothing to stop).
    """
    _, v0, a0 = (x[0] for x in follower.sample(np.array([at])))
    if np.abs(v0).max() < AT_REST and np.abs(a0).max() < AT_REST:
        return None
    # the shortest that can fit: a path at constant speed v0 needs T >= 1.875 |v0| / a at the margin
    shortest = max(STOP_MIN_S, PEAK_SPEED * float(np.abs(v0).max()) / (STOP_MARGIN * acceleration_max))
    count = max(int(np.ceil(np.log(STOP_MAX_S / shortest) / np.log(STOP_GRID))), 0) + 1
    durations = shortest * STOP_GRID ** np.arange(count)
    peak = _stop_peaks(follower, at, durations)
    plan_rest = follower.rest_time()
    for bound in (STOP_MARGIN * acceleration_max, acceleration_max * (1 + 1e-9)):
        fits = np.flatnonzero(peak <= bound)
        if not fits.size and at < plan_rest <= at + STOP_MAX_S:
            return StrutStop(float(at), float(plan_rest - at), follows_plan=True)
        if fits.size:
            k = int(fits[0])
            if k == 0:
                return StrutStop(float(at), float(durations[0]))
            finer = np.linspace(durations[k - 1], durations[k], STOP_REFINE + 2)[1:-1]  # between the last miss and it
            fine = np.flatnonzero(_stop_peaks(follower, at, finer) <= bound)
            return StrutStop(float(at), float(finer[fine[0]] if fine.size else durations[k]))
    return StrutStop(float(at), float(durations[int(np.argmin(peak))]))


def _stop_peaks(follower, at: float, durations) -> np.ndarray:
    """Peak |l''| (m/s^2) over STOP_SAMPLES samples of the stop from ``at`` with each duration [k] (s), [k]."""
    durations = np.asarray(durations, dtype=float)
    x = np.linspace(0.0, 1.0, STOP_SAMPLES)[None, :]
    ease, rate, _ = smoothstep(x)
    sigma = at + durations[:, None] * (x - smoothstep_integral(x))
    speed, curve = 1.0 - ease, -rate / durations[:, None]
    _, v, a = follower.sample(sigma.ravel())
    shape = (durations.size, STOP_SAMPLES, -1)
    accel = a.reshape(shape) * (speed * speed)[..., None] + v.reshape(shape) * curve[..., None]
    return np.abs(accel).max(axis=(1, 2))


def reserve_times(start: float, end: float, knots) -> np.ndarray:
    """Where the stop reserve is evaluated in [start, end] (s): every RESERVE_SUBGRID_S, every knot (and just
    before it: the acceleration may jump there) and inside every segment between knots its midpoint, or 4
    points if it is longer than the sub-grid step (a quintic segment's acceleration is a cubic)."""
    knots = np.asarray(knots, dtype=float)
    knots = knots[(knots >= start) & (knots <= end)]
    span = max(end - start, 0.0)
    step = max(RESERVE_SUBGRID_S, span / 200_000)
    edges = np.unique(np.concatenate([[start, end], knots]))
    widths = np.diff(edges)
    long = widths > step
    inner = np.concatenate([edges[:-1][~long] + 0.5 * widths[~long],
                            (edges[:-1][long, None] + widths[long, None] * (np.arange(1, 5) / 5.0)).ravel()])
    grid = start + step * np.arange(int(np.ceil(span / step)) if span > 0 else 0)
    return np.unique(np.concatenate([grid, edges, np.maximum(edges - 1e-9, start), inner]))


def check_stop_reserve(sample, start: float, end: float, knots, acceleration_max: float, what: str = "the trajectory",
                       reserve_s: float = STOP_RESERVE_S, rest_at: float | None = None) -> None:
    """Raise unless a stop within ``reserve_s`` exists from every instant of [start, end] (module docstring).

    Args:
        sample: times [n] -> the command's (positions, velocities, accelerations) [n, 6] (m, m/s, m/s^2).
        start, end: the span (s).
        rest_at: when the command comes to rest by itself (s, its end; default ``end``): from ``rest_at -
            reserve_s`` on it is its own stop.
        knots: the command's knot times (s).
        acceleration_max: strut_acceleration_max (m/s^2).
        what: for the message.
        reserve_s: the longest stop allowed (s).

    Raises:
        ActuatorLimitError: ``limit_name`` "stop_reserve" with ``leg`` (1..6), ``value`` (the braking it would
            need, m/s^2), ``limit`` (strut_acceleration_max) and ``time`` (s) of the first violation.
    """
    end = min(end, (end if rest_at is None else rest_at) - reserve_s)
    if end < start:
        return
    times = reserve_times(start, end, knots)
    _, v, a = sample(times)
    braking = np.maximum(0.0, -a * np.sign(v))
    need = braking + np.abs(v) * PEAK_SPEED / reserve_s
    bad = need > acceleration_max * (1 + 1e-6)
    if bad.any():
        row = int(np.argmax(bad.any(axis=1)))
        leg = int(np.argmax(need[row]))
        error = ActuatorLimitError(
            f"leg_{leg + 1}: at t = {times[row]:.4f} s {what} brakes at {braking[row, leg]:.4g} m/s^2 while moving at "
            f"{abs(v[row, leg]) * 1e3:.3f} mm/s: a stop within {reserve_s:g} s would need {need[row, leg]:.4g} m/s^2, "
            f"more than strut_acceleration_max {acceleration_max:.4g} m/s^2 (no room left to stop)", leg=leg + 1,
            limit_name="stop_reserve", value=float(need[row, leg]), limit=acceleration_max, time=float(times[row]))
        raise error
