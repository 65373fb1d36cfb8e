"""The vibrations the planning page follows (pure): any client's vibrate goal from its feedback (the plan, what
the sensors show delivered), the units' state from vibration/status, the run summary when the units come to
rest, and the page's own start command until the planner answers it.

Times are s of the suite's clock (sim time: a plan's t0, a status's ``since`` and ``time``); amplitudes m
(um on the page), angles rad (deg on the page); directions in the base frame.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..emulation.vibration_status import VibrationReport
from ..robot import Robot
from . import model
from .live_streams import RunBuffers
from .suite_status import Event, EventLog, NodeStatus

RUNNING_STATES = ("pending", "ramping_in", "running", "ramping_out")
PLANNER_STATUS = "vibration_planner: vibration planner"  # the planner's /diagnostics status name
T0_TOLERANCE_S = 1e-6  # times within this of a plan's t0 count as at it (a plan with such a t0 is the same one)


@dataclass(frozen=True)
class DeliveredFigures:
    """What a vibration's feedback says the sensors show delivered: time since t0 (s), measured frequency (Hz),
    amplitude along the planned direction (m), direction error and the legs' phase spread (rad)."""

    elapsed_s: float
    frequency_hz: float
    amplitude_m: float
    direction_error_rad: float
    phase_spread_rad: float

    @classmethod
    def of(cls, feedback) -> DeliveredFigures:
        """Of a Vibrate feedback (its fields by name)."""
        return cls(feedback.elapsed_s, feedback.frequency_hz, feedback.delivered_amplitude_m,
                   feedback.direction_error_rad, feedback.phase_spread_rad)

    def view(self) -> dict:
        """The page's view: amplitude in um, angles in deg."""
        return {"elapsed_s": self.elapsed_s, "frequency_hz": self.frequency_hz,
                "amplitude_um": self.amplitude_m * 1e6,
                "direction_error_deg": float(np.degrees(self.direction_error_rad)),
                "phase_spread_deg": float(np.degrees(self.phase_spread_rad))}


@dataclass
class FollowedRun:
    """One vibration: its start ``t0`` (s), the ``settings`` that give it again (VIBRATION_KEYS), the nominal
    pose [6] (m, rad) it ran at, who started it ("this page" / "another client"), and whether it is over."""

    t0: float
    settings: dict
    nominal: np.ndarray
    source: str
    done: bool = False


def status_events(previous: VibrationReport | None, report: VibrationReport) -> list[Event]:
    """The events a new vibration/status report is worth: a refused window or a safety ramp, the units stopped or
    e-stopped (none for the first report: what came before it is not known)."""
    if previous is None:
        return []
    events = []
    if report.event_seq != previous.event_seq and report.event in ("refused", "safety_ramp"):
        events.append(Event("hardware_emulator", f"vibration units: {report.event_text}", "WARN"))
    if report.state != previous.state and report.state in ("estopped", "stopped"):
        events.append(Event("hardware_emulator", f"vibration units {report.message}",
                            "ERROR" if report.state == "estopped" else "WARN"))
    return events


class VibrationFollow:
    """The latest units' report and delivered figures, the vibration followed and its summary. ``buffers``: the
    full-rate streams the summary is computed from; ``events``: where the units' events are logged; ``own_goal``:
    the id of the vibrate goal this page sent last."""

    def __init__(self, robot: Robot, buffers: RunBuffers, events: EventLog):
        self.robot, self.buffers, self.events = robot, buffers, events
        self.status: VibrationReport | None = None
        self.delivered: DeliveredFigures | None = None
        self.run: FollowedRun | None = None
        self.summary: dict | None = None
        self.own_goal: bytes | None = None

    @property
    def following_own_run(self) -> bool:
        """A vibration this page started is under way (the streams must stay subscribed for its summary)."""
        return self.run is not None and not self.run.done and self.run.source == "this page"

    def sent(self, goal_id: bytes) -> None:
        """The planner took this page's vibrate goal (its id): its vibration is "this page"'s."""
        self.own_goal = goal_id

    def on_feedback(self, plan: dict, settings: dict, goal_id: bytes, delivered: DeliveredFigures) -> None:
        """A vibrate goal's feedback (this page's or another client's): its ``plan`` record (t0_s, pose, ...) and
        ``settings``; a plan with a new t0 is a new vibration to follow."""
        self.delivered = delivered
        if self.run is not None and abs(self.run.t0 - plan["t0_s"]) < T0_TOLERANCE_S:
            return
        source = "this page" if goal_id == self.own_goal else "another client"
        self.run = FollowedRun(plan["t0_s"], settings, np.asarray(plan["pose"]), source)

    def on_status(self, report: VibrationReport) -> None:
        """A vibration/status report: its events are logged; the followed run is over (and summarised up to the
        units' rest at ``report.since``) once the units left the running states after its t0."""
        previous, self.status = self.status, report
        self.events.extend(status_events(previous, report))
        run = self.run
        if run is not None and not run.done and report.state not in RUNNING_STATES \
                and report.since >= run.t0 - T0_TOLERANCE_S and report.time > run.t0:
            run.done = True
            self.summary = self._summary(run, report.since)

    def _summary(self, run: FollowedRun, ended: float) -> dict:
        try:
            summary = model.run_summary(self.robot, self.buffers.joints, self.buffers.poses, self.buffers.forces,
                                        run.nominal, run.settings, run.t0, ended)
            summary["source"] = run.source
            return summary
        except Exception as exc:  # noqa: BLE001 - e.g. too short to analyse: say so on the page
            return {"t0_s": run.t0, "ended_s": ended, "error": f"{type(exc).__name__}: {exc}"}

    def view(self, planner: NodeStatus | None) -> dict | None:
        """The units' state for the page (None before the first report), with the planner's state and message
        (its /diagnostics status, None if not seen) and the delivered figures."""
        r = self.status
        if r is None:
            return None
        return {"state": r.state, "level": r.level, "reason": r.reason, "since_s": r.since, "time_s": r.time,
                "amplitude_um": (r.amplitude * 1e6).tolist(), "event": r.event_text,
                "event_outcome": r.event_outcome, "accepted": r.accepted,
                "refused": r.refused, "estopped": r.state == "estopped",
                "planner": planner.values.get("state") if planner else None,
                "planner_message": planner.message if planner else None,
                "delivered": self.delivered.view() if self.delivered else None}


@dataclass
class StartAnswer:
    """The page's start command, answered once: by the vibration's first feedback (it started), else by the
    goal's refusal or end. ``preview``: the page's preview of it (vibration_preview)."""

    reply: Callable[[dict], None]
    preview: dict
    answered: bool = False

    def answer(self, payload: dict) -> None:
        """Reply ``payload`` unless the command was answered already."""
        if not self.answered:
            self.answered = True
            self.reply(payload)

    def started(self, plan: dict) -> Event | None:
        """The first feedback's ``plan`` record: the answer (with the largest difference between the preview's
        leg amplitudes and the plan's, um) and its event; None after the answer."""
        if self.answered:
            return None
        match = float(np.abs(np.asarray(plan["leg_amplitudes_m"]) * 1e6 - self.preview["leg_amplitudes_um"]).max())
        text = (f"started: {plan['frequency_hz']:g} Hz, platform amplitude {plan['amplitude_m'] * 1e6:.3f} um "
                f"along {np.round(plan['direction_base'], 6).tolist()} (base frame), t0 = {plan['t0_s']:.6f} s")
        self.answer({"ok": True, "message": text, "plan": plan, "preview": self.preview, "preview_vs_plan_um": match})
        return Event("vibration_planner", text, "OK")

    def ended(self, outcome: str, message: str) -> Event | None:
        """The goal's result (outcome name and message): the answer if none was given yet; an event unless it
        SUCCEEDED."""
        self.answer({"ok": False, "refused_by": "vibration_planner", "outcome": outcome, "message": message,
                     "preview": self.preview})
        return None if outcome == "SUCCEEDED" else Event("vibration_planner", f"{outcome}: {message}", "WARN")

    def not_accepted(self) -> None:
        """The planner did not take the goal (or it could not be sent)."""
        self.answer({"ok": False, "refused_by": "vibration_planner", "message": "the goal was not accepted"})
