"""Stops of a force-guarded move (pure numpy): where the struts can come to rest, and how fast, when the
stop's arrival at the robot is known only within a window.

A stop is a leg trajectory stamped 0 (now) with one point: the struts come to rest at L0 + D sigma_f after T_s.
The emulator departs from the state it commands when the stop arrives, which lies on the move at a receipt
time known only within a window after the node's "now" (the receipt window); the quintic from any such
departure to (sigma_f, rest) must stay within deceleration_scale x strut_acceleration_max and
strut_velocity_max (checked on a grid of receipt times), and T_s is the shortest that does (to
STOP_RESOLUTION_S). sigma_f is the natural stopping point of the estimated departure (velocity falling as a
cubic smoothstep: sigma_f = sigma + T_s (sigma_dot / 2 + sigma_ddot T_s / 12)), so the stop follows the planned
path. If the move would end before the stop could (sigma_f >= 1), there is no stop: the move ends at its goal.
Times are s of the emulator's clock, lengths m.
"""

from __future__ import annotations

import numpy as np

from ..robot import Limits
from ..splines import quintic_hermite
from .guarded_move import GuardedMove, StopPlan

RECEIPT_DELAY_S = 0.02  # expected emulator time between the node's estimate of "now" and its command arriving
RECEIPT_WINDOW_S = 0.15  # the stop stays within the limits for any arrival within this (at least) after "now"
MAX_WINDOW_S = 0.6  # the receipt window never grows beyond this (stops would get long)
STOP_DURATIONS_S = (0.05, 5.0)  # shortest and longest stop (s)
STOP_RESOLUTION_S = 0.01
_TAU = np.linspace(0.0, 1.0, 41)  # points per stop segment at which the limits are checked
# quintic Hermite bases on _TAU for a segment of unit duration ending at rest (v1 = a1 = 0): velocity and
# acceleration per unit of (p0 - p1), v0 and a0; a segment of duration h scales them by 1/h, h^0, h
_BASES = [quintic_hermite(_TAU, 1.0, *unit, 0.0, 0.0, 0.0)[1:] for unit in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0),
                                                                          (0.0, 0.0, 1.0))]


def stop_peaks(departures, final: float, duration: float) -> tuple[np.ndarray, np.ndarray]:
    """Largest |acceleration| and |velocity| [n] (progress units: 1/s^2, 1/s) of the quintics from each
    departure state (sigma, sigma_dot, sigma_ddot, each [n]) to (``final``, rest) over ``duration`` (s)."""
    (vp, ap), (vv, av), (va, aa) = _BASES
    p0, v1, a1 = (np.asarray(x, float)[:, None] for x in departures)
    gap = p0 - final
    vel = gap * vp / duration + v1 * vv + a1 * va * duration
    acc = gap * ap / duration**2 + v1 * av / duration + a1 * aa
    return np.abs(acc).max(axis=1), np.abs(vel).max(axis=1)


def plan_stop(move: GuardedMove, limits: Limits, deceleration_scale: float, newest_state_time: float,
              window_s: float, later_s: float = 0.0) -> StopPlan | None:
    """The stop of ``move`` if commanded ``later_s`` s after ``newest_state_time`` (s, the emulator's time as the
    node knows it), for an arrival within ``window_s`` s after it, within ``deceleration_scale`` x the strut
    acceleration limit and the strut speed limit; None if the move would end first."""
    scale = move.stroke
    if scale <= 0:
        return None
    newest = newest_state_time + later_s
    t_est = newest + RECEIPT_DELAY_S
    s0, v0, a0 = (float(x[0]) for x in move.progress([t_est]))
    receipt = move.progress(newest + np.linspace(0.0, window_s, 7))
    acc_max, vel_max = deceleration_scale * limits.strut_acceleration_max / scale, limits.strut_velocity_max / scale

    def peaks(duration: float):  # the quintics from every receipt to (final, rest) over ``duration``
        final = s0 + duration * (v0 / 2 + a0 * duration / 12)
        acc, vel = stop_peaks(receipt, final, duration)
        return final, float(acc.max()), float(vel.max())

    # the shortest duration (to STOP_RESOLUTION_S) whose worst case stays within the limits: grow, then bisect
    low, high = 0.0, max(STOP_DURATIONS_S[0], 1.5 * abs(v0) / acc_max)
    final, acc, vel = peaks(high)
    while (acc > acc_max or vel > vel_max) and high < STOP_DURATIONS_S[-1]:
        low, high = high, high * 1.5
        final, acc, vel = peaks(high)
    while high - low > STOP_RESOLUTION_S and low > 0:
        mid = 0.5 * (low + high)
        f, a, v = peaks(mid)
        if a > acc_max or v > vel_max:
            low = mid
        else:
            high, final, acc = mid, f, a
    if final >= 1.0:
        return None
    return StopPlan(float(high), move.start_lengths + move.delta * final, float(final), t_est, acc * scale)


def latest_take(move: GuardedMove, stop: StopPlan, limits: Limits) -> float:
    """The latest arrival (s, emulator clock) at which the emulator still takes ``stop`` off ``move``: the
    end of the run of arrivals from ``stop.receipt_time`` (every STOP_RESOLUTION_S) whose quintic keeps
    within strut_acceleration_max and strut_velocity_max (its own check; later ones it refuses)."""
    scale = move.stroke
    arrivals = stop.receipt_time + np.arange(0.0, 2 * MAX_WINDOW_S + stop.duration, STOP_RESOLUTION_S)
    acc, vel = stop_peaks(move.progress(arrivals), stop.progress, stop.duration)
    refused = (acc * scale > limits.strut_acceleration_max) | (vel * scale > limits.strut_velocity_max)
    first_refused = int(np.argmax(refused)) if refused.any() else arrivals.size
    return float(arrivals[max(first_refused - 1, 0)])
