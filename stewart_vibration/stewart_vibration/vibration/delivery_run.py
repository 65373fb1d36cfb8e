"""One vibration as the planner delivers it (pure): its start, when a window, a correction or a stop window goes
out, when the goal's feedback is due, what the robot's vibration/status and the platform IMU say about it, and
how it ends (the outcome names of the one outcome table).

A run ends SUCCEEDED when the planner's clock passes the planned end (CANCELED after a stop), and is aborted
when the robot stops it (start_gate.robot_stop: ROBOT_REFUSED, EMERGENCY_STOPPED, PHYSICS_FAULT, a safety
ramp's outcome, STOPPED_EARLY), when the units go idle before the planned end or were never reported moving
(STOPPED_EARLY), when the planner was held up past the buffered look-ahead (HELD_UP; the units have begun
their ramp-out), or when the closed loop gives up (DELIVERY_LIMIT, after a stop window).

Times: ``now`` is the planner's clock (sim s), ``wall`` the monotonic wall clock (s); the stream's times are s
from the run's t0 (the clock's time the vibration starts, every window's stamp).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np

from ..kinematics.rotations import rotation_from_rpy
from ..robot import Robot
from .closed_loop import ClosedLoop, closed_loop_for
from .settings import start_check
from .start_gate import UNITS_MOVING, robot_stop
from .streaming import StreamInterrupted, VibrationStream, VibrationWindow
from .unit_identification import VibrationIdentification
from .waveform import envelope, fade_out

FEEDBACK_PERIOD_S = 0.1  # wall s between a goal's feedback messages
# the robot's idle this close before the planned end (s) is that end: it judges its state on its own tick
IDLE_BEFORE_END_S = 0.05
NEVER_CONFIRMED = ("the hardware emulator never reported the units vibrating for this goal (its vibration/status "
                   "stayed at rest): nothing was delivered")


@dataclass(frozen=True)
class RunEnd:
    """How a run ends: its outcome name and message; ``aborted``: the planner says why and keeps it as its state
    until the next start; ``emergency``: the robot's emergency stop (an error, not a warning)."""

    outcome: str
    message: str
    aborted: bool = True
    emergency: bool = False


@dataclass(frozen=True)
class Stop:
    """A stop: the last window to send (None: the vibration already ends by itself) and what it does, for the
    log."""

    window: VibrationWindow | None
    message: str


@dataclass(frozen=True)
class DeliveryStep:
    """What the planner does now, in this order: publish the goal's feedback, send the stop window, send the
    window, end the run."""

    feedback: bool = False
    stop: Stop | None = None
    window: VibrationWindow | None = None
    end: RunEnd | None = None


@dataclass(frozen=True)
class LoopSettings:
    """The closed loop's parameters: the fraction of the error corrected per update, the accelerometer's
    averaging interval (s) and the IMU silence that aborts (s)."""

    gain: float
    imu_average_s: float
    imu_silence_s: float


@dataclass
class DeliveryRun:
    """The running vibration: its settings (vibration.settings keys), t0 (clock s), stream and closed loop."""

    settings: dict
    t0: float
    stream: VibrationStream
    loop: ClosedLoop | None
    next_send: float  # clock s: the next streamed window is due
    seen: float  # s from t0: the clock at the last tick, from which a stall is judged
    seen_event: int  # the last command event of the robot's vibration/status already seen (its event_seq)
    stopping: bool = False  # a stop was sent: the vibration ramps out
    confirmed: bool = False  # the robot said its units moved (or changed state) since t0
    next_feedback: float = 0.0  # wall s
    ended: float | None = None  # clock s the run ended

    @property
    def listens_to_imu(self) -> bool:
        """A closed loop runs and takes the platform IMU's samples."""
        return self.loop is not None and not self.stopping

    def tick(self, now: float, wall: float) -> DeliveryStep:
        """The run at ``now`` on a tick that was not held up: its end, or the feedback, the closed loop's step
        and the window that is due."""
        rel = self.seen = now - self.t0
        end = self.stream.rest_at if self.stopping else self.stream.planned_end
        if self.stream.finished and end is not None and rel >= end:
            if self.stopping:
                return DeliveryStep(end=RunEnd("CANCELED", "cancelled: ramped out", aborted=False))
            if not self.confirmed:  # the clock ran through the plan, but the robot never said its units moved
                return DeliveryStep(end=RunEnd("STOPPED_EARLY", NEVER_CONFIRMED))
            return DeliveryStep(end=RunEnd("SUCCEEDED", "the vibration ran as planned", aborted=False))
        feedback = wall >= self.next_feedback
        if feedback:
            self.next_feedback = wall + FEEDBACK_PERIOD_S
        correct, loop = False, self.loop
        if loop is not None and not self.stopping:
            duration, ramp = self.settings["duration_s"], self.settings["ramp_s"]
            step = loop.step(rel, duration - ramp if duration > 0 else None)
            if step.action == "abort":
                limit = self.delivery_limit(now, step.reason)
                return DeliveryStep(feedback, limit.stop, end=limit.end)
            correct = step.action == "correct"
        if not correct and (self.stream.finished or now < self.next_send):
            return DeliveryStep(feedback)
        self.next_send = now + self.settings["window_period_s"]
        try:  # a correction goes at once, after the final window too (it replaces that from its splice)
            window = self.stream.correction_window(rel) if correct else self.stream.next_window(rel)
        except StreamInterrupted as exc:
            return DeliveryStep(feedback, end=RunEnd("HELD_UP", str(exc)))
        return DeliveryStep(feedback, window=window)

    def after_stall(self, held_up: float) -> DeliveryStep:
        """A tick after the planner was held up ``held_up`` s of the clock (wall s at the measured rate: the clock
        it reads is stale until it takes the /clock sent meanwhile): HELD_UP when the units ran out of commands."""
        try:
            self.stream.check_stall(self.seen, held_up)
        except StreamInterrupted as exc:
            return DeliveryStep(end=RunEnd("HELD_UP", str(exc)))
        return DeliveryStep()

    def stop(self, now: float) -> Stop:
        """Ramp out from the first sample ``lead_s`` after ``now`` (VibrationStream.stop_window); no window follows."""
        t0, stream = self.t0, self.stream
        window = stream.stop_window(now - t0)
        self.stopping = True
        if window is None:
            message = f"the vibration already ends at {t0 + stream.rest_at:.4f} s; letting it ramp out"
        elif cast(float, stream.stop_at) <= 0.0:  # a stop window sets where its ramp-out starts
            message = f"stopping before the vibration began at {t0:.4f} s: the units stay at rest"
        else:
            message = (f"stopping: ramp-out from {t0 + cast(float, stream.stop_at):.4f} s over "
                       f"{self.settings['ramp_s']} s, at rest at {t0 + window.rest_at:.4f} s")
        return Stop(window, message)

    def delivery_limit(self, now: float, reason: str) -> DeliveryStep:
        """The closed loop's abort at ``now``: ramp out, then end DELIVERY_LIMIT with ``reason``."""
        return DeliveryStep(stop=self.stop(now), end=RunEnd("DELIVERY_LIMIT", reason))

    def add_imu(self, stamp: float, accel, rate) -> str:
        """A platform IMU sample (clock s; specific force m/s^2, rate rad/s, platform frame) for the closed loop;
        why it aborts the run ("" when kept)."""
        loop = self.loop
        return loop.add_imu(stamp - self.t0, accel, rate) if loop is not None and not self.stopping else ""

    def on_status(self, report) -> RunEnd | None:
        """The robot's vibration/status ``report`` (emulation.vibration_status.VibrationReport): how it ends the
        run, or None while the run goes on."""
        t0 = self.t0
        if report.state in UNITS_MOVING or report.since > t0:  # moving, or changed state since t0 (a keep-last-1
            self.confirmed = True                              # subscriber may see only the idle at the end)
        new_event = report.event_seq != self.seen_event
        self.seen_event = report.event_seq
        stop = robot_stop(report, t0, new_event)
        if stop is not None:
            return RunEnd(*stop, emergency=report.state == "estopped")
        end = self.stream.planned_end
        if report.state == "idle" and report.since > t0 and not self.stopping and \
                (end is None or report.since < t0 + end - IDLE_BEFORE_END_S):
            return RunEnd("STOPPED_EARLY", f"the vibration units went idle at {report.since:.3f} s, before the "
                          f"planned end ({'until stop' if end is None else f'{t0 + end:.3f} s'}): {report.reason}")
        return None

    def delivered_dose(self) -> tuple[float, float]:
        """(active s: from t0 to the run's end or the units' commanded rest, whichever is first; cycles: the
        commanded envelope's integral over that time times the frequency) of an ended run."""
        s, stream = self.settings, self.stream
        end = min(self.t0 if self.ended is None else self.ended, self.t0 + stream.rest_at)
        active = max(end - self.t0, 0.0)
        if active <= 0:
            return 0.0, 0.0
        times = np.linspace(0.0, active, max(int(active / 1e-3), 2))
        weight = envelope(times, s["duration_s"] if s["duration_s"] > 0 else None, s["ramp_s"])[0]
        if stream.stop_at is not None:  # a cancel's ramp-out
            weight = weight * fade_out(times, stream.stop_at, s["ramp_s"])[0]
        return float(active), float(np.trapezoid(weight, times) * stream.plan.frequency)

    def loop_figures(self) -> tuple[int, float]:
        """The corrections the closed loop sent and how far they moved the demands (0, 0.0 without a loop;
        SineController.correction)."""
        loop = self.loop
        return (0, 0.0) if loop is None else (int(loop.controller.updates), loop.controller.correction)


def start_delivery(robot: Robot, pose, pose_stamp: float, now: float, settings: dict, wall_margin, seen_event: int,
                   identification: VibrationIdentification | None = None, loop: LoopSettings | None = None
                   ) -> tuple[DeliveryRun, VibrationWindow, str]:
    """Check and start the vibration of ``settings`` (vibration.settings.start_check) at the estimated ``pose``
    (6,) (m, rad, base frame) stamped ``pose_stamp`` at ``now`` (clock s); ``wall_margin`` maps wall s to clock s;
    ``loop``: closed on the platform IMU (it needs ``identification`` made at this pose); ``seen_event``: the
    robot's last command event.

    Returns:
        (the run, t0 = now + start lead; its first window to send now; what started, for the log).

    Raises:
        StewartError: start_check's refusal.
    """
    # just resumed from a stall, the planner may not have taken the latest /clock yet: the fresh pose estimate's
    # stamp (the same clock) bounds the present from below
    now = max(now, pose_stamp)
    started = start_check(robot, pose, settings, wall_margin, identification=identification,
                          closed_loop=loop is not None)
    plan, stream = started.plan, started.stream
    t0 = now + started.start_lead
    closed_loop, loop_note = None, ""
    if loop is not None and started.compensated and started.schedule is not None and identification is not None:
        closed_loop = closed_loop_for(robot, plan, started.schedule, stream, identification,
                                      rotation_from_rpy(np.asarray(pose)[3:]), settings["ramp_s"], loop.gain,
                                      loop.imu_average_s, loop.imu_silence_s)
        loop_note = "; closed loop on the platform IMU"
    elif loop is not None:
        loop_note = "; no closed loop: it needs the units' identification at this pose"
    run = DeliveryRun(settings, t0, stream, closed_loop, next_send=now + settings["window_period_s"], seen=now - t0,
                      seen_event=seen_event)
    summary = (f"vibrating: {plan.frequency:g} Hz, platform amplitude {plan.amplitude * 1e6:.3f} um along "
               f"{np.round(plan.direction, 6).tolist()} (base frame), t0 = {t0:.6f} s, ramp {settings['ramp_s']} s, "
               f"duration {settings['duration_s'] or 'until cancelled'} s{' (sent whole)' if stream.finished else ''}; "
               f"{started.compensation}{loop_note}")
    return run, started.first, summary
