"""Counts of malformed messages per input, and when to log them (pure).

A node ignores a malformed message and goes on with its last good state; ``MalformedCounter`` counts
it under its input (topic or service) and says whether to write a log line: the first time a reason
(``MalformedMessageError.reason``: kind and field, not the value) is seen for an input, then at most one
line per ``log_period_s`` per input, so a flood of bad messages cannot flood the log.
"""

from __future__ import annotations

import math

MAX_REASONS = 256  # distinct reasons remembered per input (reasons name a kind and a field: few exist)


class MalformedCounter:
    """Malformed messages per input: ``record`` one, ``values`` for /diagnostics."""

    def __init__(self, log_period_s: float = 1.0):
        self.log_period_s = float(log_period_s)
        self.counts: dict[str, int] = {}
        self.last: tuple[str, str] | None = None  # (input, message) of the newest
        self._reasons: dict[str, set[str]] = {}
        self._logged: dict[str, float] = {}

    @property
    def total(self) -> int:
        """Malformed messages over every input."""
        return sum(self.counts.values())

    def record(self, input_name: str, reason: str, message: str, now: float, count: int = 1) -> bool:
        """Count ``count`` malformed messages of ``input_name`` (one ``reason``, described by ``message``) at
        ``now`` (s, any monotonic clock); True when this one should be logged."""
        self.counts[input_name] = self.counts.get(input_name, 0) + count
        self.last = (input_name, message)
        seen = self._reasons.setdefault(input_name, set())
        new = reason not in seen and len(seen) < MAX_REASONS  # beyond that, new reasons log at the period
        if new:
            seen.add(reason)
        if new or now - self._logged.get(input_name, -math.inf) >= self.log_period_s:
            self._logged[input_name] = now
            return True
        return False

    def values(self) -> dict[str, str]:
        """Diagnostic key/values: ``malformed <input>`` per input, ``malformed_total`` and ``last_malformed``."""
        out = {f"malformed {name}": str(n) for name, n in sorted(self.counts.items())}
        out["malformed_total"] = str(self.total)
        if self.last is not None:
            out["last_malformed"] = f"{self.last[0]}: {self.last[1]}"
        return out
