"""The leg demands of one vibration over time (pure numpy): complex demands (vibration.leg_demands) that a
closed loop corrects while the vibration runs, each correction blended in from a time at or after the start of
the next streamed window, so every window still splices onto the one before (the samples the previous window
carried up to the splice are unchanged, and the blend starts with zero rate and acceleration).

Times are s from the vibration's t0; demands (6,) complex m; the vibration's envelope (its ramps, a stop's
fade) multiplies the samples. The decomposition's second-order terms (the legs' curvature, A^2 l''/4, a few
nanometres at clinical amplitudes) are left out: the demands are first order, as the loop measures them.
"""

from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError
from ..splines import smoothstep
from .leg_demands import blended_demand_samples


class DemandSchedule:
    """The demands from t0 on: ``initial`` (6,) complex, then each ``correct`` blended in."""

    def __init__(self, initial, frequency: float, blend_s: float = 0.1):
        self.frequency = float(frequency)
        self.blend_s = float(blend_s)
        if not self.blend_s > 0:
            raise InvalidInputError(f"blend_s must be > 0 s, got {blend_s!r}")
        self.changes: list[tuple[float, np.ndarray]] = [(-np.inf, self._checked(initial))]

    @staticmethod
    def _checked(demands) -> np.ndarray:
        u = np.asarray(demands, dtype=complex).reshape(6)
        if not np.isfinite(u).all():
            raise InvalidInputError("leg demands must be finite")
        return u

    @property
    def current(self) -> np.ndarray:
        """The latest demands (6,) complex m (those in force once every blend has ended)."""
        return self.changes[-1][1].copy()

    @property
    def settled_at(self) -> float:
        """From when (s from t0) the latest demands hold unblended."""
        at = self.changes[-1][0]
        return at + self.blend_s if np.isfinite(at) else -np.inf

    def correct(self, demands, at: float) -> None:
        """Go to ``demands`` (6,) complex from ``at`` (s from t0) over ``blend_s``: ``at`` must be at or after
        the previous correction's end (one blend at a time), and at or after the start of the next window the
        caller sends (so no sample already sent changes)."""
        if at < self.settled_at - 1e-12:
            raise InvalidInputError(f"a correction at {at:.4f} s overlaps the blend ending at {self.settled_at:.4f} s")
        self.changes.append((float(at), self._checked(demands)))

    def demand_at(self, t: float) -> np.ndarray:
        """The complex demands (6,) m in force at ``t`` (s from t0), a blend's part way included."""
        k = max(i for i, (at, _) in enumerate(self.changes) if i == 0 or at <= t)
        if k == 0:
            return self.changes[0][1].copy()
        at, after = self.changes[k]
        before = self.changes[k - 1][1]
        return before + (after - before) * float(smoothstep((t - at) / self.blend_s)[0])

    def sample(self, times, envelope) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity, acceleration (N, 6) at ``times`` (N,) s from t0 under ``envelope``
        (e, e', e'') (N,) each."""
        t = np.asarray(times, dtype=float)
        out = [np.zeros((t.size, 6)) for _ in range(3)]
        starts = [at for at, _ in self.changes[1:]] + [np.inf]
        for k, (at, demand) in enumerate(self.changes):
            # the samples this demand (blending in from the one before) governs: until the next change
            part = (t >= at) & (t < starts[k]) if k else t < starts[0]
            if not part.any():
                continue
            before = self.changes[k - 1][1] if k else demand
            env = tuple(np.asarray(e, dtype=float)[part] for e in envelope)
            samples = blended_demand_samples(t[part], self.frequency, before, demand,
                                             at if k else 0.0, self.blend_s, env)
            for column, values in zip(out, samples):
                column[part] = values
        return out[0], out[1], out[2]
