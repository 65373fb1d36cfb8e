"""What the legs deliver of the vibration units' demands, from the sensors (pure numpy).

The units of a robot as built do not move as commanded: a resonant unit answers its demand with its own gain
and phase, and the reaction shakes the strut it sits on. Newton-Euler driven by the demanded accelerations
then models forces the legs never exert (on the realistic plant 2-90x the 35 Hz force amplitude).

Per leg, the sensed hinge length (strut encoder plus unit sensor) is fitted over a window of states against the
unit's demand x_i, its rate v_i, a constant and a straight line in time (the struts' own slow motion):

    y_i ~ alpha_i x_i + beta_i v_i + c_i + d_i (t - t_mean)

For a demand at one frequency w that is the leg's complex response alpha + j beta w, whatever its source
(unit, strut, delay); the delivered acceleration is then alpha_i a_i + beta_i jerk_i, with the demand's jerk
taken as -w^2 v_i (w^2 = -<a, x> / <x, x> over the same window). A leg keeps its demand (alpha 1, beta 0) where
the fit cannot be a unit's response: a demand below ``min_demand_m`` RMS over the window (no vibration, another
unit identified), slower than MIN_FIT_FREQUENCY_HZ, or a response above MAX_RESPONSE.

The windows are fixed spans of the states' stamps, [k W, (k + 1) W) for whole k, and the states of window k
use the fit of window k - 1: what a state is modelled with depends on the recorded states only, not on how
they were batched, so a replay of a run reproduces its estimates.
"""

from __future__ import annotations

import numpy as np

FIT_WINDOW_S = 0.1  # s of states fitted: 3.5 periods at 35 Hz, 2 at the therapy band's lowest 20 Hz
MIN_DEMAND_M = 1e-7  # RMS demand over the window below which a leg is taken to follow its demand
MIN_STATES = 8  # states a window needs to be fitted
# a demand slower than this (under 1.5 periods in a window) is not fitted: its sinusoid cannot be told from the
# struts' own motion there, and a unit that slow follows its demand
MIN_FIT_FREQUENCY_HZ = 15.0
# a fitted response larger than this is no unit's (resonant units amplify 1.5-2.1x in the therapy band): the
# window held something else (a hostile command's stray demand, a move), and the leg is taken to follow its demand
MAX_RESPONSE = 4.0


class DeliveredUnits:
    """The legs' response to the unit demands, fitted per window of stamps from the sensors; ``add`` maps the
    demanded unit motion to the delivered hinge-length acceleration (see the module docstring)."""

    def __init__(self, window_s: float = FIT_WINDOW_S, min_demand_m: float = MIN_DEMAND_M):
        self.window_s, self.min_demand = float(window_s), float(min_demand_m)
        self._index: int | None = None  # the window being filled
        self._parts: list = []  # its states: (stamps [n], lengths [n, 6], demand x, v, a [n, 6] each)
        self._fit: tuple[int, tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None  # (window, (alpha, beta, w^2))

    def reset(self) -> None:
        """Forget every state and fit (time went back): the legs follow their demands until refitted."""
        self._index, self._parts, self._fit = None, [], None

    def add(self, stamps, lengths, demand) -> np.ndarray:
        """States [n] in time order: stamps (s), the sensed hinge lengths [n, 6] (m) and the units' demand (x m,
        v m/s, a m/s^2) [n, 6] each at those stamps. Returns the delivered
        hinge-length accelerations [n, 6] (m/s^2) beyond the struts' commanded motion, each state's from the fit
        of the window before its own."""
        stamps = np.asarray(stamps, float)
        lengths = np.asarray(lengths, float)
        x, v, a = (np.asarray(part, float) for part in demand)
        windows = np.floor(stamps / self.window_s).astype(np.int64)
        if self._index is not None and len(windows) and windows[0] < self._index:
            self.reset()
        out = np.empty_like(a)
        for k in np.unique(windows):
            rows = windows == k
            if self._index is not None and k != self._index:  # the window being filled is complete
                self._close()
            self._index = int(k)
            self._parts.append((stamps[rows], lengths[rows], x[rows], v[rows], a[rows]))
            fitted = self._fit is not None and self._fit[0] == int(k) - 1
            alpha, beta, omega2 = self._fit[1] if fitted else (np.ones(6), np.zeros(6), np.zeros(6))  # type: ignore[index]
            out[rows] = alpha * a[rows] - beta * omega2 * v[rows]
        return out

    def _close(self) -> None:
        """Fit the window being filled and keep only the fit the next window needs."""
        t, y, x, v, a = (np.concatenate([p[j] for p in self._parts]) for j in range(5))
        self._fit = (int(self._index), fit_response(t, y, x, v, a, self.min_demand))  # type: ignore[arg-type]
        self._parts = []


def fit_response(t, y, x, v, a, min_demand_m: float = MIN_DEMAND_M) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(alpha, beta (s), w^2 (1/s^2)) (6,) each of the legs' sensed lengths y [n, 6] (m) at stamps t [n] (s)
    against the demands x, v, a [n, 6]: least squares y ~ alpha x + beta v + c + d (t - t_mean) per leg; alpha 1,
    beta 0 for a leg whose demand is below ``min_demand_m`` RMS or slower than MIN_FIT_FREQUENCY_HZ, whose fit is
    singular or larger than MAX_RESPONSE, and for fewer than MIN_STATES states."""
    n = len(y)
    alpha, beta, omega2 = np.ones(6), np.zeros(6), np.zeros(6)
    if n < MIN_STATES:
        return alpha, beta, omega2
    power = (x * x).sum(axis=0)
    k = np.flatnonzero(power > n * min_demand_m**2)
    if not k.size:
        return alpha, beta, omega2
    # centred columns: the constant drops out; per leg the normal equations of (x, v, t) [legs, 3, 3]
    tc = (np.asarray(t, float) - np.mean(t))[:, None] * np.ones(len(k))
    xc, vc, yc = (z[:, k] - z[:, k].mean(axis=0) for z in (x, v, y))
    columns = np.stack([xc, vc, tc], axis=2)  # [n, legs, 3]
    normal = np.einsum("nli,nlj->lij", columns, columns)
    right = np.einsum("nli,nl->li", columns, yc)
    scale = np.sqrt(np.einsum("lii->li", normal))
    scaled = normal / (scale[:, :, None] * scale[:, None, :])
    solvable = np.linalg.cond(scaled) < 1e8
    coef = np.zeros((len(k), 3))
    if solvable.any():
        coef[solvable] = np.linalg.solve(scaled[solvable], (right / scale)[solvable][..., None])[..., 0] \
            / scale[solvable]
    rate2 = np.maximum(-(a[:, k] * x[:, k]).sum(0) / power[k], 0.0)
    response = np.hypot(coef[:, 0], coef[:, 1] * np.sqrt(rate2))
    plausible = solvable & (rate2 >= (2 * np.pi * MIN_FIT_FREQUENCY_HZ) ** 2) & (response <= MAX_RESPONSE)
    alpha[k] = np.where(plausible, coef[:, 0], 1.0)
    beta[k] = np.where(plausible, coef[:, 1], 0.0)
    omega2[k] = np.where(plausible, rate2, 0.0)
    return alpha, beta, omega2
