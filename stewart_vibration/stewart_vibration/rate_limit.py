"""A token-bucket rate limiter (pure): how often a command is taken from an input that could flood a node."""

from __future__ import annotations


class RateLimiter:
    """Token bucket: ``rate`` per second, bursts of ``burst``; ``allow(now)`` takes a token if there is one."""

    def __init__(self, rate: float, burst: float):
        self.rate, self.burst = float(rate), float(burst)
        self.last: float | None
        self.tokens, self.last = float(burst), None

    def allow(self, now: float) -> bool:
        """Take a token at ``now`` (s) if one is left; True when the action is allowed."""
        if self.last is not None:
            self.tokens = min(self.burst, self.tokens + (now - self.last) * self.rate)
        self.last = now
        if self.tokens >= 1.0:
            self.tokens -= 1.0
            return True
        return False


class RepeatedLine:
    """Suppresses a log line equal to the last one within ``interval_s``: ``line(text, now)`` returns the text to
    log (with how often the previous line was suppressed, if it was) or None to log nothing."""

    def __init__(self, interval_s: float = 1.0):
        self.interval_s = float(interval_s)
        self.text: str | None = None
        self.logged_at = float("-inf")
        self.suppressed = 0

    def line(self, text: str, now: float) -> str | None:
        """The line to log for ``text`` at ``now`` (s), or None while it repeats the last within interval_s."""
        if text == self.text and now - self.logged_at < self.interval_s:
            self.suppressed += 1
            return None
        out = text if not self.suppressed else f"{text} ({self.suppressed} repeats of the previous line not logged)"
        self.text, self.logged_at, self.suppressed = text, now, 0
        return out
