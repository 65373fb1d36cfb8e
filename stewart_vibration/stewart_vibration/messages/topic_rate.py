"""A topic's rate as a subscriber that loses nothing sees it (pure): messages per second of wall time and,
for stamped messages, per second of the publisher's clock, with the samples missing from the stamps.

The suite's 500 Hz streams leave in bursts (10 samples every 20 ms of sim time); a listener with a queue
shorter than a burst (``ros2 topic hz`` listens best effort with a queue of 5) drops samples and reports a
lower rate. The stamps tell the publisher's true rate whatever the arrival pattern.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np


@dataclass(frozen=True)
class TopicRate:
    """``count`` messages over ``wall_s`` (s, first to last arrival): ``wall_hz``; for stamped messages the
    stamps' span ``stamp_span_s`` (s), ``stamp_hz`` (messages per second of the stamps' clock), the stamp
    period (the median step, s), ``missing`` (samples the stamps say never arrived: steps of k periods count
    k - 1) and ``largest_gap_s``; NaN / 0 where there is not enough to say."""

    count: int
    wall_s: float
    wall_hz: float
    stamped: bool
    stamp_span_s: float = float("nan")
    stamp_hz: float = float("nan")
    period_s: float = float("nan")
    missing: int = 0
    largest_gap_s: float = float("nan")

    def record(self) -> dict:
        """Plain values for JSON (NaN as None)."""
        return {k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in asdict(self).items()}


def topic_rate(arrivals_s, stamps_s=None) -> TopicRate:
    """The rate of messages that arrived at wall times ``arrivals_s`` [n] (s, in arrival order) with header
    stamps ``stamps_s`` [n] (s; None for unstamped messages, NaN for a message without a stamp)."""
    arrivals = np.asarray(arrivals_s, float)
    count = int(arrivals.size)
    wall = float(arrivals.max() - arrivals.min()) if count > 1 else float("nan")
    wall_hz = (count - 1) / wall if count > 1 and wall > 0 else float("nan")
    if stamps_s is None:
        return TopicRate(count, wall, wall_hz, False)
    stamps = np.sort(np.asarray(stamps_s, float)[np.isfinite(np.asarray(stamps_s, float))])
    if stamps.size < 2 or stamps[-1] <= stamps[0]:
        return TopicRate(count, wall, wall_hz, True)
    steps = np.diff(stamps)
    positive = steps[steps > 1e-9]
    period = float(np.median(positive)) if positive.size else float("nan")
    missing = int(np.sum(np.maximum(np.round(positive / period) - 1, 0))) if positive.size else 0
    span = float(stamps[-1] - stamps[0])
    return TopicRate(count, wall, wall_hz, True, span, (stamps.size - 1) / span, period, missing,
                     float(steps.max()))
