"""Streaming one planned vibration to the vibration units as self-contained windows (pure numpy).

What the vibration planner node schedules (it only adds the clock and the messages). Times are
relative to the vibration's common start t0 (the header stamp of every window); samples lie on the
grid k * sample_period_s.

- A finite vibration (duration_s > 0) whose end is within ``max_lookahead_s`` of now is sent
  whole in its first window (ramp-in, steady part, ramp-out): late delivery of later windows cannot
  shorten it because there are none.
- Otherwise every window starts at s = max(now + lead_s, 0) and carries the vibration up to
  s + lookahead_s, followed by a ramp-out to zero over ramp_s (its safety tail): if no later window
  arrives, the units ramp out smoothly at the end of what they have. The next window starts on a
  sample that the previous one carried at full amplitude (before its tail), where both agree exactly,
  so the receiver splices it on continuously and the tail is replaced.
- If the planner was held up so long that the next window would start after the previous window's
  tail began, the units are already ramping out (or at rest); a continuation cannot splice there, and
  the stream reports that it was interrupted (``StreamInterrupted``) instead of sending it.
- ``stop`` sends a last window that ramps the vibration out from the first sample at or after
  now + lead_s (where the previous window is still at full amplitude).
- A correction of the demands (a closed loop's) goes out at once in ``correction_window``: the next window,
  or, once the final window was sent, the rest of the vibration again from the splice on, as long as that
  lies before the vibration's ramp-out (``can_correct``). The demands blend in from the splice, so it joins
  the window it replaces exactly there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import cast

import numpy as np

from ..errors import StewartError
from ..robot import Robot
from .decompose import VibrationDecomposition
from .demand_schedule import DemandSchedule
from .signals import sample_leg_vibration
from .waveform import envelope, fade_out, product_rule


class StreamInterrupted(StewartError):
    """The stream cannot continue: the receiver's buffer has run into its ramp-out (``at``: time it began, s)."""

    def __init__(self, message: str, at: float):
        super().__init__(message)
        self.at = at


@dataclass(frozen=True)
class StreamSettings:
    """Timing of a stream (s). duration: None = until stop (else incl. both ramps)."""

    duration: float | None
    ramp_s: float = 0.2
    sample_period_s: float = 0.001
    lookahead_s: float = 2.0
    lead_s: float = 0.3
    max_lookahead_s: float = 5.0


@dataclass(frozen=True)
class VibrationWindow:
    """One window: times [n] (s from t0), position / velocity / acceleration [n, 6] (m, m/s, m/s^2) of
    vib_1..6; ``rest_at``: time (s from t0) from which it commands rest; ``final``: no window follows."""

    times: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    rest_at: float
    final: bool


class VibrationStream:
    """Windows of one vibration (see the module docstring). ``now`` arguments are s from t0."""

    def __init__(self, robot: Robot, plan: VibrationDecomposition, settings: StreamSettings,
                 demands: DemandSchedule | None = None):
        self.robot, self.plan, self.settings = robot, plan, settings
        self.demands = demands  # complex leg demands a loop corrects; None: the plan's exact leg signals
        self.tail_start: float | None = None  # where the last window's ramp-out began (None: it ends at rest)
        self.rest_at: float = 0.0  # the last window sent commands rest from here on
        self.stop_at: float | None = None  # start of the stop ramp, once stop() was called
        self.finished = False  # the final window was sent
        self.windows_sent = 0

    # -- grid ------------------------------------------------------------------------------
    def _ceil(self, t: float) -> float:
        dt = self.settings.sample_period_s
        return max(math.ceil(t / dt - 1e-9), 0) * dt

    def splice_time(self, now: float) -> float:
        """Where the next window sent at ``now`` (s from t0) starts: a correction of ``demands`` from there on
        changes no sample already sent."""
        return self._start_after(now) if self.windows_sent else 0.0

    def _start_after(self, now: float) -> float:
        """Where a window sent at ``now`` (s from t0) starts: the first sample at or after now + lead_s."""
        return self._ceil(max(now + self.settings.lead_s, 0.0))

    def _grid(self, start: float, stop: float) -> np.ndarray:
        dt = self.settings.sample_period_s
        k0, k1 = math.ceil(start / dt - 1e-9), math.floor(stop / dt + 1e-9)
        times = np.arange(k0, k1 + 1) * dt
        if times.size == 0 or times[-1] < stop - 1e-12:
            times = np.append(times, stop)
        return times

    @property
    def planned_end(self) -> float | None:
        """Time (s from t0) at which the vibration is planned to be at rest (None: until stop)."""
        if self.stop_at is not None:
            return self.stop_at + self.settings.ramp_s
        return self.settings.duration

    def _sample(self, times: np.ndarray, fade_at: float | None, final: bool) -> VibrationWindow:
        s = self.settings
        fade = fade_out(times, fade_at, s.ramp_s) if fade_at is not None else None
        rest_at = float(times[-1])
        if self.demands is not None:
            env = envelope(times, s.duration, s.ramp_s)
            position, velocity, acceleration = self.demands.sample(
                times, product_rule(env, fade) if fade is not None else env)
            return VibrationWindow(times, position, velocity, acceleration, rest_at, final)
        legs = sample_leg_vibration(self.robot, self.plan, times, duration=s.duration, ramp_time=s.ramp_s,
                                    fade=fade)
        return VibrationWindow(times, legs.position, legs.velocity, legs.acceleration, rest_at, final)

    # -- windows ------------------------------------------------------------------------------
    def next_window(self, now: float) -> VibrationWindow | None:
        """The window to send at ``now`` (s from t0), or None when nothing is left to send.

        Raises StreamInterrupted when the previous window's ramp-out has begun before this one could
        start (the planner was held up longer than the look-ahead)."""
        if self.finished:
            return None
        s = self.settings
        # the first window starts at t0 from rest (ramp-in); later ones lead_s ahead of now
        start = self._start_after(now) if self.windows_sent else 0.0
        self._check_splice(start, "")
        end = s.duration
        if end is not None and end <= now + s.max_lookahead_s:
            window = self._sample(self._grid(start, end), None, final=True)
            self.tail_start = None
        else:
            tail: float | None
            tail = self._ceil(start + s.lookahead_s)
            if end is not None and tail + s.ramp_s >= end:
                window = self._sample(self._grid(start, end), None, final=True)
                tail = None
            else:
                window = self._sample(self._grid(start, tail + s.ramp_s), tail, final=False)
            self.tail_start = tail
        self._sent(window)
        return window

    def can_correct(self, now: float) -> bool:
        """Whether a change of the demands made at ``now`` (s from t0) can still be sent: the window it goes in
        (from ``splice_time(now)``) starts before the vibration ramps out -- no stop was sent, the last window's
        tail has not begun there, and a finite vibration's own ramp-out is still ahead."""
        if self.demands is None or self.stop_at is not None or not self.windows_sent:
            return False
        start = self.splice_time(now)
        if self.tail_start is not None and start > self.tail_start + 1e-9:
            return False
        end = self.settings.duration
        return end is None or start < end - self.settings.ramp_s - 1e-9

    def correction_window(self, now: float) -> VibrationWindow | None:
        """The window that carries a change of the demands made at ``now`` (s from t0), to send at once: the
        next window; after the final window, the rest of the vibration from ``splice_time(now)`` again (it
        replaces the final window from there). None when the change can no longer be sent (``can_correct``).

        Raises StreamInterrupted as ``next_window``."""
        if not self.can_correct(now):
            return None
        if not self.finished:
            return self.next_window(now)
        end = cast(float, self.settings.duration)  # a finished stream without a stop ends at its duration
        window = self._sample(self._grid(self._start_after(now), end), None, final=True)
        self._sent(window)
        return window

    def check_stall(self, seen: float, held_up: float) -> None:
        """Judge a stall of the sender without a fresh clock: it last saw ``seen`` (s from t0) and was then
        held up for ``held_up`` s of the receiver's clock (wall seconds times the clock rate).

        The same rule as ``next_window``: the stream is interrupted when a window sent now, at
        seen + held_up, would start after the last window's ramp-out began. Nothing is left to judge
        once the final window was sent.

        Raises:
            StreamInterrupted: the stall outlasted the commands the receiver had buffered.
        """
        if not self.finished:
            self._check_splice(self._start_after(seen + held_up),
                               f"the planner was held up {held_up:.3f} s of sim time from t0 + {seen:.3f} s: ")

    def _check_splice(self, start: float, cause: str) -> None:
        """Raise StreamInterrupted when a window starting at ``start`` (s from t0) cannot splice onto the last
        one: its ramp-out began before (``cause`` prefixes the message)."""
        if self.tail_start is not None and start > self.tail_start + 1e-9:
            raise StreamInterrupted(
                f"{cause}the next window would start at t0 + {start:.3f} s, after the last window's ramp-out began "
                f"at t0 + {self.tail_start:.3f} s: the vibration units ran out of commands (the planner was held up "
                f"{start - self.tail_start:.3f} s too long)", at=self.tail_start)

    def stop_window(self, now: float) -> VibrationWindow | None:
        """A last window ramping out from the first sample at or after now + lead_s (s from t0), or None
        when the vibration already ends by then (its own ramp-out or the last window's tail). Either
        way no further window is sent. A stop that lands before t0 sends a window of rest from t0 on: it
        replaces what the units hold, and they never move."""
        s = self.settings
        start = self._start_after(now)
        ends_by = self.tail_start if self.tail_start is not None else self.rest_at - (
            s.ramp_s if s.duration is not None and self.rest_at >= s.duration - 1e-9 else 0.0)
        if start >= ends_by:
            if self.tail_start is not None:
                self.stop_at = self.tail_start
            self.finished = True
            return None
        self.stop_at = start
        times = self._grid(start, start + s.ramp_s)
        if start <= 0.0:  # stopped before it began: the units stay at rest (no ramp-in to ramp out)
            still = np.zeros((times.size, 6))
            window = VibrationWindow(times, still, still.copy(), still.copy(), float(times[-1]), True)
        else:
            window = self._sample(times, start, final=True)
        self.tail_start = None
        self._sent(window)
        return window

    def _sent(self, window: VibrationWindow) -> None:
        self.rest_at = window.rest_at
        self.finished = window.final
        self.windows_sent += 1
