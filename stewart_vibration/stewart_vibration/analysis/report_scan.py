"""The run report's whole-run figures, computed as a recording streams past (pure numpy): each plotted series as
a min/max envelope, a running mean, where the vibration units are active, and the leg-force model's error over
the whole run. Fed batch after batch (each stream in its recorded order) they hold a few thousand rows whatever
the run's length; fed the whole run at once they give the same figures.

Times in s (header stamps, or s from the run's first message as the caller keeps them); values in the caller's
units.
"""

from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError
from ..vibration.sine_fit import SineSums
from .fits import force_error_figures

PLOT_BINS = 2000  # a whole-run line is drawn as this many min/max pairs at least, twice as many at most


class StreamEnvelope:
    """A series [n, m] reduced for a line plot as it arrives: up to 2 ``bins`` samples are kept as they are;
    beyond, consecutive runs of k samples (k doubling as the series grows, so that there are between ``bins``
    and 2 ``bins`` runs) each become a vertical stroke from their min to their max (non-finite samples left
    out of both), drawn between the run's first time and the next run's. Every peak stays drawn."""

    def __init__(self, width: int, bins: int = PLOT_BINS):
        self.bins, self.k = int(bins), 1
        self.t_first = np.empty(0)
        self.lo, self.hi = np.empty((0, width)), np.empty((0, width))
        self.partial: tuple[float, np.ndarray, np.ndarray, int] | None = None  # (first time, lo, hi, samples)
        self.last_t = np.nan

    def add(self, t, y) -> None:
        """The next samples: times [n] (s) and values [n, m]."""
        t = np.asarray(t, float)
        if not t.size:
            return
        y = np.asarray(y, float).reshape(t.size, -1)
        self.last_t = float(t[-1])
        i = 0
        while i < t.size:
            if self.partial is not None:
                first, lo, hi, count = self.partial
                take = min(self.k - count, t.size - i)
                part = y[i:i + take]
                lo, hi = np.fmin(lo, np.fmin.reduce(part, axis=0)), np.fmax(hi, np.fmax.reduce(part, axis=0))
                i += take
                self.partial = None
                if count + take == self.k:
                    self._close(np.array([first]), lo[None], hi[None])
                else:
                    self.partial = (first, lo, hi, count + take)
                continue
            full = (t.size - i) // self.k
            if not full:
                part = y[i:]
                self.partial = (float(t[i]), np.fmin.reduce(part, axis=0), np.fmax.reduce(part, axis=0), t.size - i)
                break
            k, end = self.k, i + full * self.k  # closing may double k
            block = y[i:end].reshape(full, k, -1)
            self._close(t[i:end:k], np.fmin.reduce(block, axis=1), np.fmax.reduce(block, axis=1))
            i = end

    def _close(self, t_first: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> None:
        """Runs of k samples completed; pairs merge (k doubles) while there are more than 2 ``bins`` runs, an
        odd last one going back to being the partial run of the doubled k."""
        self.t_first = np.concatenate([self.t_first, t_first])
        self.lo, self.hi = np.concatenate([self.lo, lo]), np.concatenate([self.hi, hi])
        while self.t_first.size > 2 * self.bins:
            if self.t_first.size % 2:  # the odd last run and what follows it make the new partial run
                lo, hi, count = self.lo[-1], self.hi[-1], self.k
                if self.partial is not None:
                    _first, plo, phi, pcount = self.partial
                    lo, hi, count = np.fmin(lo, plo), np.fmax(hi, phi), count + pcount
                self.partial = (float(self.t_first[-1]), lo, hi, count)
                self.t_first, self.lo, self.hi = self.t_first[:-1], self.lo[:-1], self.hi[:-1]
            self.t_first = self.t_first[0::2]
            self.lo = np.fmin(self.lo[0::2], self.lo[1::2])
            self.hi = np.fmax(self.hi[0::2], self.hi[1::2])
            self.k *= 2

    @property
    def samples(self) -> int:
        """How many samples went in."""
        return self.t_first.size * self.k + (self.partial[3] if self.partial is not None else 0)

    def result(self) -> tuple[np.ndarray, np.ndarray]:
        """(times [p], values [p, m]): the samples themselves while there are at most 2 ``bins``; else each run
        as its min then its max, both at the middle of the run's span."""
        if self.k == 1 and self.partial is None:
            return self.t_first.copy(), self.lo.copy()
        t_first, lo, hi = self.t_first, self.lo, self.hi
        if self.partial is not None:
            first, plo, phi, _count = self.partial
            t_first = np.append(t_first, first)
            lo, hi = np.vstack([lo, plo[None]]), np.vstack([hi, phi[None]])
        middle = 0.5 * (t_first + np.append(t_first[1:], self.last_t))
        return np.repeat(middle, 2), np.stack([lo, hi], axis=1).reshape(-1, lo.shape[1])


class RunningMean:
    """The mean of the finite rows [n, m] seen so far (NaN before any)."""

    def __init__(self, width: int):
        self.total, self.count = np.zeros(width), 0

    def add(self, y) -> None:
        """Rows [n, m] (finite ones: the caller leaves the others out)."""
        y = np.asarray(y, float)
        self.total += y.sum(axis=0)
        self.count += y.shape[0]

    def result(self) -> np.ndarray:
        """The mean row [m]."""
        return self.total / self.count if self.count else np.full(self.total.shape, np.nan)


class VibrationActivity:
    """When the vibration units were active: the first and last sample whose largest |vib_i| exceeds ``share``
    of the run's largest, found as the samples stream past (only the samples that could still be either are
    kept: the rising records for the first, the falling ones for the last)."""

    def __init__(self, share: float = 0.02):
        self.share = share
        self.rising_t, self.rising = np.empty(0), np.empty(0)  # each above every earlier sample
        self.falling_t, self.falling = np.empty(0), np.empty(0)  # each above every later sample so far

    def add(self, t, vib) -> None:
        """Samples: times [n] (s), displacements [n, 6] (finite rows)."""
        t = np.asarray(t, float)
        if not t.size:
            return
        level = np.abs(np.asarray(vib, float)).max(axis=1)
        before = self.rising[-1] if self.rising.size else -np.inf
        records = level > np.maximum.accumulate(np.concatenate([[before], level[:-1]]))
        self.rising_t = np.concatenate([self.rising_t, t[records]])
        self.rising = np.concatenate([self.rising, level[records]])
        later = np.concatenate([np.maximum.accumulate(level[::-1])[::-1][1:], [-np.inf]])
        tail = level > later  # above every later sample of this batch
        keep = self.falling > level.max()  # earlier ones a sample of this batch does not reach
        self.falling_t = np.concatenate([self.falling_t[keep], t[tail]])
        self.falling = np.concatenate([self.falling[keep], level[tail]])

    def span(self) -> tuple[float, float] | None:
        """(first, last) time above ``share`` of the largest level; None without samples or with all of them 0."""
        if not self.rising.size or self.rising[-1] <= 0:
            return None
        threshold = self.share * self.rising[-1]
        first = self.rising_t[np.flatnonzero(self.rising > threshold)[0]]
        last = self.falling_t[np.flatnonzero(self.falling > threshold)[-1]]
        return float(first), float(last)


class ForceErrorScan:
    """``fits.force_error`` over a whole run whose estimates and measurements arrive in batches: each measured
    sample within the estimates' span against the estimates linearly interpolated to its time; RMS per leg, and
    as the measured forces' amplitude their half peak-to-peak, or with ``frequency`` (Hz) their fitted oscillation
    (``SineSums`` over ``window``, s: the span the samples lie in)."""

    def __init__(self, width: int = 6, frequency: float | None = None, window: tuple[float, float] = (0.0, 1.0)):
        self.est_t, self.est = np.empty(0), np.empty((0, width))
        self.first_est = np.nan
        self.meas_t, self.meas = np.empty(0), np.empty((0, width))
        self.squares, self.count = np.zeros(width), 0
        self.high, self.low = np.full(width, -np.inf), np.full(width, np.inf)
        self.estimates = 0
        self.sums = SineSums(frequency, width, window) if frequency else None

    def add_estimates(self, t, forces) -> None:
        """Estimated leg forces: times [n] (s), forces [n, 6] (N), in their recorded order."""
        t = np.asarray(t, float)
        if not t.size:
            return
        if not self.estimates:
            self.first_est = float(t[0])
        self.estimates += t.size
        self.est_t, self.est = np.concatenate([self.est_t, t]), np.concatenate([self.est, np.asarray(forces, float)])
        self._match()

    def add_measured(self, t, forces) -> None:
        """Measured leg forces: times [n] (s), forces [n, 6] (N), in their recorded order."""
        t = np.asarray(t, float)
        if not t.size:
            return
        self.meas_t = np.concatenate([self.meas_t, t])
        self.meas = np.concatenate([self.meas, np.asarray(forces, float)])
        self._match()

    def _match(self) -> None:
        """Measured samples up to the newest estimate are compared (those before the first estimate dropped);
        the estimates from the last one at or before the newest measured time stay (the left neighbours of the
        measured samples still to come, which are no older)."""
        if not self.est_t.size or not self.meas_t.size:
            return
        newest = self.meas_t[-1]
        ready = self.meas_t <= self.est_t[-1]
        use = ready & (self.meas_t >= self.first_est)
        tm, fm = self.meas_t[use], self.meas[use]
        if tm.size:
            est = np.stack([np.interp(tm, self.est_t, self.est[:, k]) for k in range(self.est.shape[1])], axis=1)
            self.squares += ((est - fm) ** 2).sum(axis=0)
            self.count += tm.size
            self.high, self.low = np.maximum(self.high, fm.max(axis=0)), np.minimum(self.low, fm.min(axis=0))
            if self.sums is not None:
                self.sums.add(tm, fm)
        self.meas_t, self.meas = self.meas_t[~ready], self.meas[~ready]
        keep = max(int(np.searchsorted(self.est_t, newest, side="right")) - 1, 0)
        self.est_t, self.est = self.est_t[keep:], self.est[keep:]

    def result(self) -> dict | None:
        """force_error's dict; None with fewer than four estimates. Raises InvalidInputError when fewer than four
        measured samples lie within the estimates' span (as force_error)."""
        return self._figures(self.estimates, self.squares, self.count, self.high - self.low, self.sums)

    def combined(self, other: ForceErrorScan) -> dict | None:
        """``result`` of this scan's samples and ``other``'s together (two parts of a run, each part's measured
        samples against that part's estimates; the same frequency and window)."""
        sums = self.sums.merged(other.sums) if self.sums is not None and other.sums is not None else None
        high, low = np.maximum(self.high, other.high), np.minimum(self.low, other.low)
        return self._figures(self.estimates + other.estimates, self.squares + other.squares,
                             self.count + other.count, high - low, sums)

    @staticmethod
    def _figures(estimates: int, squares: np.ndarray, count: int, peak_to_peak: np.ndarray,
                 sums: SineSums | None) -> dict | None:
        if estimates < 4:
            return None
        if count < 4:
            raise InvalidInputError("force_error: the estimate and measurement do not overlap")
        rms = np.sqrt(squares / count)
        amplitude = sums.fit().amplitude if sums is not None else peak_to_peak / 2
        return force_error_figures(rms, amplitude, count)
