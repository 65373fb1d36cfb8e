"""The load a force-guarded move will reach (pure numpy): the force or moment magnitude estimated during the
move, fitted against the move's progress sigma and extrapolated to the progress at which a stop would end.

The fit is a quadratic least squares in sigma around the latest progress (linear with few samples or little
spread), continued as an exponential with the fit's local growth rate while the load rises: soft tissue
stiffens with distraction, and a quadratic under-predicts an exponential the further it looks ahead.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FIT_WINDOW_S = 0.15  # estimate history fitted against the progress (s of sim time)
MIN_FIT_SAMPLES = 8
MAX_EXTRAPOLATION = 5.0  # the fit is extrapolated at most this many times its own span of progress
TREND_SIGNIFICANCE = 3.0  # a mean rise of up to this many standard errors is noise: not extrapolated
PROVEN_TREND = 10.0  # from this many standard errors on the trend is extrapolated whole (a tissue's is ~100)
MAX_GROWTH_EXPONENT = 2.0  # the exponential continuation of the fit grows at most e^2 - 1 times its slope / rate


def predict_load(samples, column: int, target_progress: float) -> tuple[float, float]:
    """(latest value, predicted value at ``target_progress``) of column 2 (force, N) or 3 (moment, N m) of the
    (t, sigma, |F|, |M|) samples: quadratic least squares in sigma around the latest progress (linear with
    few samples or little spread; the latest value when the progress does not change), extrapolated with the
    fit's slope F' and curvature F'' at the latest progress as an exponential while the load rises
    (F + F' (exp(r d) - 1) / r, r = F''/F', d the progress ahead); an easing load is never predicted to
    rise. A mean change over the window within TREND_SIGNIFICANCE standard errors of none is noise, not a
    trend: then the prediction is the fitted level plus that many noise deviations (never below the latest
    value), so a load already at its limit is still stopped; from there to PROVEN_TREND standard errors the
    rise's extrapolation is phased in."""
    rows = np.asarray(samples, float)
    now = float(rows[-1, column])
    if len(rows) < MIN_FIT_SAMPLES:
        return now, now
    x = rows[:, 1] - rows[-1, 1]
    span = float(np.ptp(x))
    ahead = max(target_progress - rows[-1, 1], 0.0)
    if span < 1e-6:
        return now, now
    degree = 2 if len(rows) >= 2 * MIN_FIT_SAMPLES and span > 0.2 * ahead else 1
    u, load = x / span, rows[:, column]
    coef = np.polyfit(u, load, degree)
    residual = load - np.polyval(coef, u)
    noise = float(np.sqrt(residual @ residual / (len(u) - degree - 1)))
    # a: how far ahead, in spans of the fitted progress; capped, since a trend seen over a sliver of progress (a
    # fast move's first estimates, model error of a few N) extrapolated a hundred spans ahead predicts kilonewtons
    a = min(ahead / span, MAX_EXTRAPOLATION)
    polynomial = float(np.polyval(coef, a) - np.polyval(coef, 0.0))
    rise = _mean_rise_significance(u, load, noise)
    if rise < -TREND_SIGNIFICANCE:  # easing over the window: never predicted to rise
        return now, now + min(polynomial, 0.0)
    if rise <= TREND_SIGNIFICANCE:  # a trend the noise explains: the fitted level now, raised by its noise band
        return now, max(now, float(coef[-1]) + TREND_SIGNIFICANCE * noise)
    proven = min((rise - TREND_SIGNIFICANCE) / (PROVEN_TREND - TREND_SIGNIFICANCE), 1.0)
    slope, curvature = float(coef[-2]), (2.0 * float(coef[0]) if degree == 2 else 0.0)
    if slope <= 0 or abs(curvature) < 1e-9 * slope:  # not rising here, or straight: the polynomial itself
        return now, now + proven * polynomial
    # rising: continue with the local growth rate r = F''/F' (exponential stiffening keeps it): F' (e^{ra} - 1)/r,
    # never below the quadratic (its Taylor series has the quadratic's terms and more of the same sign). r a is
    # capped: on a load that is mostly noise (no tissue) r is noise over noise, and e^{ra} would run away
    rate = curvature / slope
    return now, now + proven * max(polynomial, slope * float(np.expm1(min(rate * a, MAX_GROWTH_EXPONENT))) / rate)


def _mean_rise_significance(u: np.ndarray, load: np.ndarray, noise: float) -> float:
    """The t statistic of the load's mean rise over the window: its straight line's slope per span of progress
    ``u`` over the slope's standard error, with ``noise`` the fit's residual deviation (+-inf without noise)."""
    centred = u - u.mean()
    sxx = float(centred @ centred)
    slope = float(centred @ load) / sxx
    if noise <= 0:
        return float(np.copysign(np.inf, slope)) if slope else 0.0
    return slope * np.sqrt(sxx) / noise


@dataclass(frozen=True)
class LoadVerdict:
    """The force and moment predicted at a stop's end (N, N m; NaN for a limit that is off) and, when one of them
    rises past its limit, which ("force" or "moment"), that limit, and the latest and predicted force and moment
    to report (a limit that is off reports the latest value for both)."""

    predicted: tuple[float, float]
    which: str | None = None
    limit: float = 0.0
    load: tuple[float, float] = (float("nan"), float("nan"))
    predicted_at_trip: tuple[float, float] = (float("nan"), float("nan"))


def judge_load(samples, baseline: tuple, limits: tuple[float, float], target_progress: float) -> LoadVerdict:
    """Whether the load of the (t, sigma, |F|, |M|) ``samples`` passes a limit (force N, moment N m; 0 = off) at
    ``target_progress``: its prediction there is over the limit, it rises, and it has risen above the move's
    ``baseline`` (force, moment at its start) by 1 % of the limit (a move that relieves a load already over the
    limit is not stopped). Force is judged before moment."""
    checks = {}
    predicted_load = [float("nan"), float("nan")]
    for which, column, limit, base in (("force", 2, limits[0], baseline[0]), ("moment", 3, limits[1], baseline[1])):
        if limit <= 0:
            continue
        now, predicted = predict_load(samples, column, target_progress)
        predicted_load[column - 2] = float(predicted)
        checks[which] = (now, predicted, limit, now > base + 0.01 * limit and predicted > now)
    verdict = LoadVerdict((predicted_load[0], predicted_load[1]))
    over = next(((which, c[2]) for which, c in checks.items() if c[3] and c[1] > c[2]), None)
    if over is None:
        return verdict
    latest = samples[-1]
    f = checks.get("force", (latest[2], latest[2]))
    m = checks.get("moment", (latest[3], latest[3]))
    return LoadVerdict(verdict.predicted, over[0], over[1], (float(f[0]), float(m[0])), (float(f[1]), float(m[1])))
