"""One identification of the vibration units as the planner runs it (pure): its session's windows when they are
due, the goal's feedback, the robot's stops, and its end -- the identification judged and written once every
step has run and the robot reports its units at rest, or the outcome that ended it first.

Times: ``now`` and stamps are the planner's clock (sim s), ``wall`` the monotonic wall clock (s); the session's
times are s from the run's t0.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import StewartError
from ..robot import VIB_NAMES
from .delivery_run import FEEDBACK_PERIOD_S
from .identification_run import ExcitationStep
from .identification_session import IdentificationSession
from .start_gate import BUSY_STATES, robot_stop
from .unit_identification import quality_problems, save_identification

# a step's window is sent this long (clock s) before it starts: a planner held up for less delays nothing (the
# robot queues it behind the step it runs)
QUEUE_S = 1.0
END_MARGIN_S = 0.1  # clock s after the last step's end before the run may conclude
REST_REPORT_WAIT_S = 3.0  # clock s after the last step for the robot's report of its units at rest
METHOD = "stepped sine, unit sensors and IMU"


@dataclass(frozen=True)
class IdentificationEnd:
    """How the run ended: the outcome name and message, the file written ("" if none), the problems that
    rejected it, and how long it ran (s from t0)."""

    outcome: str
    message: str
    path: str = ""
    problems: list[str] = field(default_factory=list)
    duration_s: float = 0.0


@dataclass(frozen=True)
class IdentificationStep:
    """What the planner does now: send ``windows`` ((stamp clock s, times s from it, position, velocity,
    acceleration (N, 6) of vib_1..6) each), publish ``progress`` as feedback ((step, steps, unit, frequency Hz);
    None: not due), and conclude when ``ready``."""

    windows: list[tuple] = field(default_factory=list)
    progress: tuple[int, int, int, float] | None = None
    ready: bool = False


@dataclass
class IdentificationRunner:
    """The run of ``session`` from ``t0`` (clock s); the result goes to ``path`` (YAML)."""

    session: IdentificationSession
    t0: float
    queue_s: float  # clock s: a step's window is sent this long before it starts
    path: Path
    date: str  # when it started, for the file's provenance
    seen_event: int  # the last command event of the robot's vibration/status already seen (its event_seq)
    next_feedback: float = 0.0  # wall s
    end: IdentificationEnd | None = None

    @classmethod
    def start(cls, steps: list[ExcitationStep], amplitude_m: float, pose, now: float, lead: float, path: Path,
              seen_event: int) -> IdentificationRunner:
        """A run of ``steps`` at ``pose`` (6,) (m, rad, base frame) with each unit's demand ``amplitude_m`` (m),
        started at ``now`` with t0 ``lead`` later (clock s)."""
        return cls(IdentificationSession(steps, amplitude_m, pose), now + lead, max(lead, QUEUE_S), path,
                   time.strftime("%Y-%m-%d %H:%M:%S"), seen_event)

    @property
    def summary(self) -> str:
        """What runs, for the log."""
        steps = self.session.steps
        return (f"identifying the vibration units: {len(steps)} steps at {sorted({x.frequency for x in steps})} Hz, "
                f"{self.session.amplitude_m * 1e6:g} um, {steps[-1].end:.1f} s")

    def tick(self, now: float, wall: float, cancel_requested: bool, report) -> IdentificationStep:
        """The run at ``now``; ``report``: the robot's latest vibration/status (VibrationReport, None before one).
        A cancel ends it CANCELED with nothing written."""
        rel = now - self.t0
        if cancel_requested and self.end is None:
            self.end = IdentificationEnd("CANCELED", "cancelled: no further step, nothing written")
            return IdentificationStep()
        windows = [(self.t0 + start, *samples) for start, *samples in self.session.due_windows(rel, self.queue_s)]
        progress = None
        if wall >= self.next_feedback:
            self.next_feedback = wall + FEEDBACK_PERIOD_S
            progress = self.session.progress(rel)
        return IdentificationStep(windows, progress, self._ready(rel, report))

    def _ready(self, rel: float, report) -> bool:
        """Every step has run and the robot reports its units at rest since (a vibration started next is refused
        before that), or the wait for that report ran out."""
        end = self.session.end
        if rel < end + END_MARGIN_S or self.end is not None:
            return False
        at_rest = report is not None and report.time >= self.t0 + end and report.state not in BUSY_STATES
        return at_rest or rel >= end + REST_REPORT_WAIT_S

    def conclude(self, gravity, accel_average_s: float, unit_sensor_latency_s: float) -> IdentificationEnd:
        """The identification from the samples (IdentificationSession.identification), judged
        (unit_identification.quality_problems) and written to ``path``; the run's end."""
        duration = self.session.end
        try:
            found = self.session.identification(gravity, accel_average_s, unit_sensor_latency_s,
                                                {"date": self.date, "method": METHOD})
        except StewartError as exc:
            self.end = IdentificationEnd("IDENTIFICATION_REJECTED", f"no identification: {exc}", "", [str(exc)],
                                         duration)
            return self.end
        problems = quality_problems(found)
        if problems:
            self.end = IdentificationEnd("IDENTIFICATION_REJECTED", f"{len(problems)} problems, first: {problems[0]}",
                                         "", problems, duration)
            return self.end
        try:
            path = str(save_identification(self.path, found))
        except OSError as exc:
            self.end = IdentificationEnd("INVALID_ARGUMENT", f"could not write {self.path}: {exc}", "",
                                         [f"not written: {exc}"], duration)
            return self.end
        self.end = IdentificationEnd("SUCCEEDED", f"identified at {len(found.frequencies)} frequencies: {path}", path,
                                     [], duration)
        return self.end

    def on_status(self, report) -> None:
        """The robot's vibration/status ``report`` (VibrationReport): a stop of the robot's
        (start_gate.robot_stop) ends the run with nothing written."""
        new_event = report.event_seq != self.seen_event
        self.seen_event = report.event_seq
        if self.end is not None:
            return
        stop = robot_stop(report, self.t0, new_event)
        if stop is not None:
            name, reason = stop
            self.end = IdentificationEnd(name, f"identification stopped, nothing written: {reason}", "", [reason],
                                         max(report.since - self.t0, 0.0))

    def add_imu(self, stamp: float, accel, rate) -> None:
        """A platform IMU sample (clock s; specific force m/s^2, rate rad/s, platform frame)."""
        self.session.add_imu(stamp - self.t0, accel, rate)

    def add_unit_readings(self, stamp: float, names, positions) -> None:
        """A legs/joint_states sample (clock s; joint ``names``, ``positions`` m): its vib_1..6 readings; one
        without every unit, or with positions that do not match the names, is left out."""
        index = {name: k for k, name in enumerate(names)}
        positions = np.asarray(positions, dtype=float)
        if all(name in index for name in VIB_NAMES) and positions.size == len(names):
            self.session.add_units(stamp - self.t0, positions[[index[n] for n in VIB_NAMES]])
