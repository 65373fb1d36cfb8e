"""What the vibration units are really doing, as the emulator reports it (pure; vibration/status).

``VibrationStatusTracker`` turns the command buffer's classification (idle, pending, ramping_in,
running, ramping_out), the e-stop and the command events (window accepted / refused, safety ramps)
into one report with a state that names why it stopped, the time it entered that state and an
event counter, so a reader (planner, runner, estimator, UI) can tell a normal end from a watchdog,
an e-stop or a refused window.

States: idle, pending (a window starts later), ramping_in, running, ramping_out, stopped (at rest
after a safety ramp: watchdog, stop), estopped (latched until reset; also after a physics fault, which the
``fault`` value names).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .vibration_buffer import BufferStatus

OK, WARN, ERROR = "ok", "warn", "error"
EMERGENCY_STOP = "emergency stop"  # the reason of the e-stop's safety ramp (ramp_reason)
DEACTIVATED = "deactivated"  # lifecycle deactivate: a safety stop without the e-stop's latch
SHUTDOWN = "shutdown"  # the emulator stopping: the robot brakes to rest first
PHYSICS_FAULT = "physics fault"  # the divergence detector latched (the robot is held)
# the causes of a safety ramp (index = VibrationUnitsStatus RAMP_* constant); a reason above names its cause
RAMP_CAUSES = ("", "watchdog", "emergency_stop", "deactivated", "shutdown", "physics_fault", "unit_protection")
CAUSE_OF = {EMERGENCY_STOP: "emergency_stop", DEACTIVATED: "deactivated", SHUTDOWN: "shutdown",
            PHYSICS_FAULT: "physics_fault"}
STRUT_STOP_CAUSES = ("emergency_stop", "deactivated", "shutdown")  # safety ramps that also brake the struts
# the outcome (Outcome.msg) of the event of a safety ramp of each cause
RAMP_OUTCOMES = {"watchdog": "STOPPED_EARLY", "emergency_stop": "EMERGENCY_STOPPED", "deactivated": "ROBOT_INACTIVE",
                 "shutdown": "SHUTDOWN", "physics_fault": "PHYSICS_FAULT", "unit_protection": "UNIT_TRAVEL_STOPPED"}
STATES = ("idle", "pending", "ramping_in", "running", "ramping_out", "stopped", "estopped")  # = the msg's constants
LEVELS = (OK, WARN, ERROR)  # = DiagnosticStatus levels 0, 1, 2
EVENTS = ("", "accepted", "refused", "safety_ramp")  # = VibrationUnitsStatus EVENT_* constants


@dataclass(frozen=True)
class VibrationReport:
    """One vibration/status message (times in s of the emulator's clock). ``event``: the last command event (one of
    EVENTS), with its outcome (a name of Outcome.msg) and reason; ``ramp_cause``: one of RAMP_CAUSES."""

    state: str
    level: str
    reason: str
    since: float
    time: float
    amplitude: np.ndarray = field(default_factory=lambda: np.zeros(6))
    commanded_until: float = float("-inf")
    ramp_start: float | None = None
    ramp_reason: str = ""
    ramp_cause: str = ""
    event_seq: int = 0
    event: str = ""
    event_outcome: str = ""
    event_reason: str = ""
    event_stamp: float | None = None
    event_time: float | None = None
    accepted: int = 0
    refused: int = 0
    fault: str = ""  # a latched physics fault's reason ("" if none)
    active: bool = True  # the robot takes commands (the node's lifecycle state: active)

    @property
    def message(self) -> str:
        """The state and, if any, its reason as one line ("state: reason")."""
        return f"{self.state}: {self.reason}" if self.reason else self.state

    @property
    def event_text(self) -> str:
        """The last event for people ("refused (LIMIT_EXCEEDED): ..."; "" before one)."""
        return f"{self.event} ({self.event_outcome}): {self.event_reason}" if self.event else ""


class VibrationStatusTracker:
    """Keeps the current report; ``update`` and the event methods return it (and whether it changed)."""

    def __init__(self):
        self.report = VibrationReport(state="idle", level=OK, reason="no vibration commanded yet", since=0.0,
                                      time=0.0)
        self._stopped_reason = ""  # reason of the last safety ramp, until a new vibration starts

    def _event(self, now: float, event: str, outcome: str, reason: str, stamp: float | None = None,
               **counts) -> VibrationReport:
        r = self.report
        self.report = replace(r, event_seq=r.event_seq + 1, event=event, event_outcome=outcome, event_reason=reason,
                              event_stamp=stamp, event_time=now, **counts)
        return self.report

    def accepted(self, now: float, stamp: float) -> VibrationReport:
        """Record an accepted window (start ``stamp``, s) at ``now`` (s); clears the stop reason, returns the report."""
        self._stopped_reason = ""
        return self._event(now, "accepted", "SUCCEEDED", "window accepted", stamp, accepted=self.report.accepted + 1)

    def refused(self, now: float, stamp: float, outcome: str, reason: str) -> VibrationReport:
        """Record a refused window (start ``stamp``, s) at ``now`` (s), its ``outcome`` (a name of Outcome.msg) and
        ``reason``; returns the report."""
        return self._event(now, "refused", outcome, reason, stamp, refused=self.report.refused + 1)

    def safety_ramp(self, now: float, reason: str, cause: str) -> VibrationReport:
        """Record a safety ramp to zero from ``now`` (s) for ``reason`` of ``cause`` (RAMP_CAUSES); returns the
        report."""
        self._stopped_reason = reason
        return self._event(now, "safety_ramp", RAMP_OUTCOMES[cause], f"ramp to zero: {reason}")

    def update(self, buffer: BufferStatus, estopped: bool, now: float,
               fault: str | None = None) -> tuple[VibrationReport, bool]:
        """Fold the buffer's classification at ``now`` into the report; (report, state changed). ``fault``: a
        latched physics fault's reason (the state is "estopped" with level ERROR and the fault named)."""
        r = self.report
        if buffer.ramp_start is not None and buffer.ramp_start <= now and buffer.ramp_reason:
            self._stopped_reason = self._stopped_reason or buffer.ramp_reason
        if fault:
            state, level = "estopped", ERROR
            reason = f"physics fault: {fault}; the robot is held (reconfigure the emulator)"
        elif estopped:
            state, level = "estopped", ERROR
            reason = ("emergency stop latched (vibration ramped to zero, struts stopped and held); "
                      "call hardware_emulator/reset")
        elif buffer.state == "idle" and self._stopped_reason:
            state, level, reason = "stopped", WARN, self._stopped_reason
        elif buffer.state == "idle":
            state, level = "idle", OK
            reason = (f"commands ended at {buffer.commanded_until:.3f} s" if np.isfinite(buffer.commanded_until)
                      else "no vibration commanded yet")
        elif buffer.state == "ramping_out" and buffer.ramp_start is not None and buffer.ramp_start <= now:
            state, level, reason = "ramping_out", WARN, buffer.ramp_reason
        elif buffer.state == "ramping_out":
            state, level, reason = "ramping_out", OK, f"commands end at {buffer.commanded_until:.3f} s"
        else:
            state, level = buffer.state, OK
            reason = f"commanded until {buffer.commanded_until:.3f} s"
        changed = state != r.state or level != r.level
        since = now if changed else r.since
        self.report = replace(r, state=state, level=level, reason=reason, since=since, time=now,
                              amplitude=buffer.amplitude, commanded_until=buffer.commanded_until,
                              ramp_start=buffer.ramp_start, ramp_reason=buffer.ramp_reason,
                              ramp_cause=buffer.ramp_cause, fault=fault or "")
        return self.report, changed
