"""Health of a high-rate input stream as a node sees it (pure): samples received, lost, processed
and how late, for /diagnostics and the run summary.

Lost samples are found from the stamps: the stream's period is the smallest positive stamp step seen
(e.g. 2 ms at 500 Hz); a step of k periods means k - 1 samples never arrived. Lag is the wall time
from a sample's arrival to the publication of its output (the node's own processing delay).
"""

from __future__ import annotations

from collections import deque

import numpy as np

LAG_WINDOW = 2000  # recent samples kept for the lag percentiles


class StreamHealth:
    """Counters of one input stream (stamps in s, wall times in s)."""

    def __init__(self, behind_lag_s: float = 0.05):
        self.behind_lag_s = behind_lag_s
        self.received = 0
        self.processed = 0
        self.lost = 0
        self.rejected = 0
        self.period = np.inf
        self._last_stamp: float | None = None
        self._lags: deque = deque(maxlen=LAG_WINDOW)

    def arrived(self, stamps) -> None:
        """Stamps [n] of samples that arrived, in arrival order."""
        stamps = np.asarray(stamps, float)
        if not stamps.size:
            return
        self.received += stamps.size
        chain = stamps if self._last_stamp is None else np.concatenate([[self._last_stamp], stamps])
        steps = np.diff(chain)
        positive = steps[steps > 1e-9]
        if positive.size:
            self.period = min(self.period, float(positive.min()))
            if np.isfinite(self.period):
                self.lost += int(np.maximum(np.round(positive / self.period) - 1, 0).sum())
        if steps.size and (steps < -1e-9).any():  # time went backwards (a restarted clock): start over
            self.period = np.inf
        self._last_stamp = float(stamps[-1])

    def done(self, arrival_walls, publish_wall: float) -> None:
        """Outputs published at ``publish_wall`` for samples that arrived at ``arrival_walls`` [n]."""
        arrival_walls = np.asarray(arrival_walls, float)
        self.processed += arrival_walls.size
        self._lags.extend((publish_wall - arrival_walls).tolist())

    def lag_percentiles_ms(self) -> tuple[float, float]:
        """(p50, p99) of the recent processing lags, ms (0 if none)."""
        if not self._lags:
            return 0.0, 0.0
        p50, p99 = np.percentile(np.fromiter(self._lags, float), [50, 99])
        return float(p50) * 1e3, float(p99) * 1e3

    @property
    def behind(self) -> bool:
        """True when samples were lost or the recent p99 lag exceeds ``behind_lag_s``."""
        return self.lost > 0 or self.lag_percentiles_ms()[1] > self.behind_lag_s * 1e3

    def values(self, prefix: str = "input") -> dict[str, str]:
        """Diagnostic key/values."""
        p50, p99 = self.lag_percentiles_ms()
        return {f"{prefix}_received": str(self.received), f"{prefix}_processed": str(self.processed),
                f"{prefix}_lost": str(self.lost), f"{prefix}_rejected": str(self.rejected),
                f"{prefix}_lag_p50_ms": f"{p50:.2f}", f"{prefix}_lag_p99_ms": f"{p99:.2f}"}


class SequenceGaps:
    """Samples missing from the publication sequence numbers of each topic's one publisher (pure counter).

    A DDS writer numbers its samples 1, 2, 3, ...; a reader that sees n after m lost n - m - 1 of them. A
    number lower than the last one is a new publisher (a restarted node): counting starts again from it.
    Only meaningful for topics with a single publisher (the numbers of several writers interleave).
    """

    def __init__(self) -> None:
        self._last: dict[str, int] = {}
        self._missing: dict[str, int] = {}

    def seen(self, topic: str, sequence) -> None:
        """The sample numbered ``sequence`` of ``topic`` arrived (None or a non-integer: ignored)."""
        if not isinstance(sequence, int) or isinstance(sequence, bool) or sequence <= 0:
            return
        last = self._last.get(topic)
        if last is not None and sequence > last + 1:
            self._missing[topic] = self._missing.get(topic, 0) + sequence - last - 1
        self._last[topic] = sequence

    @property
    def total(self) -> int:
        """Samples missing over every topic."""
        return sum(self._missing.values())

    def per_topic(self) -> dict[str, int]:
        """{topic: samples missing} of the topics that missed any."""
        return {t: n for t, n in self._missing.items() if n}

