"""What the legs deliver of the vibration units' demands, from the sensors (pure numpy).

The units of a robot as built do not move as commanded: a resonant unit answers its demand with its own gain
and phase, and the reaction shakes the strut it sits on. Newton-Euler driven by the demanded accelerations
then models forces the legs never exert (on the realistic plant 2-90x the 35 Hz force amplitude).

Per leg, the sensed deviation of the hinge length from the commanded strut length,

    y_i = (strut encoder_i - strut command_i) + unit sensor_i,

is fitted over the last ``window_s`` of states against the unit's demand x_i, its rate v_i and a constant:

    y_i ~ alpha_i x_i + beta_i v_i + c_i

For a demand at one frequency w that is the leg's complex response alpha + j beta w, whatever its source
(unit, strut, delay); the delivered acceleration is then alpha_i a_i + beta_i jerk_i, with the demand's jerk
taken as -w^2 v_i (w^2 = -<a, x> / <x, x> over the same window). A leg whose demand is below
``min_demand_m`` RMS over the window (no vibration, another unit identified) keeps the demand (alpha 1, beta 0).
"""

from __future__ import annotations

from collections import deque

import numpy as np

FIT_WINDOW_S = 0.1  # s of states fitted: 3.5 periods at 35 Hz, 2 at the therapy band's lowest 20 Hz
MIN_DEMAND_M = 1e-7  # RMS demand over the window below which a leg is taken to follow its demand


class DeliveredUnits:
    """The legs' response to the unit demands (``alpha``, ``beta`` (6,), s for beta), refitted as states arrive;
    ``accelerations`` maps demanded unit motion to the delivered hinge-length acceleration."""

    def __init__(self, window_s: float = FIT_WINDOW_S, min_demand_m: float = MIN_DEMAND_M):
        self.window_s, self.min_demand = float(window_s), float(min_demand_m)
        self._batches: deque = deque()  # (stamps [n], deviation [n, 6], demand x, v, a [n, 6] each)
        self.alpha, self.beta, self.omega2 = np.ones(6), np.zeros(6), np.zeros(6)

    def reset(self) -> None:
        """Forget the states (time went back): the legs follow their demands until refitted."""
        self._batches.clear()
        self.alpha, self.beta, self.omega2 = np.ones(6), np.zeros(6), np.zeros(6)

    def add(self, stamps, deviation, demand) -> None:
        """States [n]: stamps (s), the sensed hinge-length deviation from the strut command [n, 6] (m) and the
        units' demand (x m, v m/s, a m/s^2) [n, 6] each at those stamps; refits from the window ending at the
        newest."""
        stamps = np.asarray(stamps, float)
        if not stamps.size:
            return
        if self._batches and self._batches[-1][0][-1] > stamps[0]:
            self.reset()
        x, v, a = (np.asarray(part, float) for part in demand)
        self._batches.append((stamps, np.asarray(deviation, float), x, v, a))
        cutoff = stamps[-1] - self.window_s
        while self._batches and self._batches[0][0][-1] < cutoff:
            self._batches.popleft()
        self._fit(cutoff)

    def _fit(self, cutoff: float) -> None:
        t = np.concatenate([b[0] for b in self._batches])
        keep = t >= cutoff
        y, x, v, a = (np.concatenate([b[k] for b in self._batches])[keep] for k in range(1, 5))
        n = int(keep.sum())
        alpha, beta, omega2 = np.ones(6), np.zeros(6), np.zeros(6)
        power = (x * x).sum(axis=0)
        fitted = (n >= 8) & (power > n * self.min_demand**2)
        if fitted.any():
            k = np.flatnonzero(fitted)
            # centred columns: the constant drops out of the 2x2 normal equations
            xc, vc, yc = (z[:, k] - z[:, k].mean(axis=0) for z in (x, v, y))
            sxx, svv, sxv = (xc * xc).sum(0), (vc * vc).sum(0), (xc * vc).sum(0)
            sxy, svy = (xc * yc).sum(0), (vc * yc).sum(0)
            det = sxx * svv - sxv**2
            solvable = det > 1e-12 * sxx * svv
            alpha[k] = np.where(solvable, (svv * sxy - sxv * svy) / np.where(solvable, det, 1.0), 1.0)
            beta[k] = np.where(solvable, (sxx * svy - sxv * sxy) / np.where(solvable, det, 1.0), 0.0)
            omega2[k] = np.maximum(-(a[:, k] * x[:, k]).sum(0) / power[k], 0.0)
        self.alpha, self.beta, self.omega2 = alpha, beta, omega2

    def accelerations(self, demand) -> np.ndarray:
        """The hinge-length accelerations [n, 6] (m/s^2) the legs deliver for the units' demand (x, v, a) [n, 6]
        each, beyond the struts' commanded motion."""
        _x, v, a = (np.asarray(part, float) for part in demand)
        return self.alpha * a - self.beta * self.omega2 * v
