"""What the hardware emulator reports and when (pure Python): vibration/status at once on news and again
while unchanged, refused commands counted with their log lines thinned, a latched physics fault or e-stop
first in its health message, and which of many repeated events get a log line. Times in s of wall time.
"""

from __future__ import annotations

import time

from .physics_guard import PhysicsFault


def thinned(count: int, first: int, every: int) -> bool:
    """Whether the ``count``-th occurrence (from 1) of a repeating event gets a log line: the first ``first``,
    then every ``every``-th (a fault that repeats every state period would flood the log)."""
    return count <= first or count % every == 0


def latched_first(message: str, fault: PhysicsFault | None, estopped: bool) -> str:
    """``message`` with a latched physics fault (its sim time in s and reason), else a latched e-stop, in front:
    whatever else the health message says, what holds the robot is read first."""
    if fault is not None:
        return (f"physics fault latched at {fault.time:.3f} s: {fault.reason}; robot held (cleanup + configure to "
                f"rebuild); {message}")
    if estopped:
        return f"emergency stop latched (call hardware_emulator/reset to clear); {message}"
    return message


class StatusRepeats:
    """When vibration/status goes out: a report with news (it changed, or carries a command event not sent
    yet) at once; an unchanged one again once ``repeat_s`` of wall time has passed since the last one sent
    (its amplitudes and times move on). Both the executor and the physics thread send reports.

    Args:
        repeat_s: wall time between repeats of an unchanged status (s).
        clock: the wall clock (s, monotonic; injectable for tests).
    """

    def __init__(self, repeat_s: float, clock=time.monotonic):
        self.repeat_s = float(repeat_s)
        self.clock = clock
        # (event_seq, wall time) of the last report sent, one tuple so that a reader on another thread never
        # sees the sequence of one send with the time of another
        self._last = (-1, float("-inf"))

    def sent(self, event_seq: int) -> None:
        """A report with command event ``event_seq`` went out now."""
        self._last = (event_seq, self.clock())

    def is_news(self, event_seq: int, changed: bool) -> bool:
        """Whether an evaluated report (``changed``: its state differs from the last evaluation) goes out now."""
        return changed or event_seq != self._last[0]

    def repeat_due(self) -> bool:
        """Whether an unchanged status goes out again now. The repeat timer runs every repeat_s too: a status
        sent a little less than repeat_s ago (timer jitter) does not put the repeat off by a whole period."""
        return self.clock() - self._last[1] >= self.repeat_s * 0.9


class RejectionTally:
    """Refused commands: every one counted; a log line for the first of each kind (what was refused and the
    first clause of why) and then at most one per ``period_s`` of wall time, since a sender that keeps sending
    the same bad command would otherwise flood the log.

    Args:
        period_s: wall time between log lines of one kind (s).
        clock: the wall clock (s, monotonic; injectable for tests).
    """

    def __init__(self, period_s: float = 1.0, clock=time.monotonic):
        self.period_s = float(period_s)
        self.clock = clock
        self.count = 0
        self._logged_at: dict[tuple[str, str], float] = {}  # kind -> wall time of its last log line (s)

    def add(self, what: str, reason: str) -> bool:
        """Count a refused ``what`` (e.g. "leg trajectory") with ``reason``; True when it gets a log line."""
        self.count += 1
        kind = (what, reason.split(":")[0])
        now = self.clock()
        if now - self._logged_at.get(kind, float("-inf")) >= self.period_s:
            self._logged_at[kind] = now
            return True
        return False
