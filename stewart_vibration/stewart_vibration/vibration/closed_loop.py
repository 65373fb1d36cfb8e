"""The closed loop of one streamed vibration (pure): the platform IMU's samples in, the corrected leg demands
(or an abort with its reason) out, on the stream's splice rules.

Each update takes the IMU samples of the last ``measure_periods`` whole periods that lie after the latest
correction has blended in and after the ramp-in, demodulates them against the demands' carrier
(vibration.frequency_response.platform_motion), and lets the SineController correct the demands; the
correction is blended in from the next window's start (``VibrationStream.splice_time``), so the caller sends
that window at once (``VibrationStream.correction_window``: after the final window too, until the ramp-out).
An IMU that goes silent or too sparse to measure (fewer than MIN_SAMPLES over the measured periods, for
longer than ``silence_s`` past when a measurement was due), or reports what no vibration of this size can be
(non-finite values, an acceleration beyond ``plausible_g``), aborts the vibration: the loop cannot see what it
delivers. An abort names the units that deliver off their demand (SineController.with_unit_fault).

Times are s from the vibration's t0 (the stream's clock); the IMU's samples are platform-frame specific force
(m/s^2) and rate (rad/s).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from ..robot import STANDARD_GRAVITY, Robot
from .compensation import target_motion
from .decompose import VibrationDecomposition
from .demand_schedule import DemandSchedule
from .frequency_response import platform_motion
from .sine_control import ControlStep, SineController, delivered_figures, judge
from .streaming import VibrationStream
from .unit_identification import VibrationIdentification

MIN_SAMPLES = 8  # IMU samples a measurement needs over its measure_periods
# the planner's defaults (parameters.tables declares them from these; the loop gain is sine_control's, beside its
# stability margins): the IMU's silence that aborts
DEFAULT_IMU_SILENCE_S = 0.1
DEFAULT_IMU_AVERAGE_S = 0.002  # the emulated IMU integrates and dumps over its sample period (500 Hz)


@dataclass(frozen=True)
class LoopStep:
    """What the caller does now: "wait" (nothing), "correct" (send the next window at once), "abort" (ramp out
    and end the goal with ``reason``); ``control``: the controller's step of a correction or abort (None when
    the abort is the sensor's)."""

    action: str
    reason: str = ""
    control: ControlStep | None = None


class ClosedLoop:
    """The loop of one vibration (module docstring).

    Args:
        controller: the SineController (its demands are the schedule's initial ones).
        schedule: the DemandSchedule the stream samples.
        stream: the VibrationStream of the vibration.
        rotation: the platform's nominal orientation (3, 3) in the base frame; gravity (3,) m/s^2 there.
        ramp_s: the vibration's ramp-in (s): nothing is measured before its end.
        accel_average_s: the accelerometer's averaging interval (its sample period, s).
        silence_s: an IMU sample older than this (s of the stream's clock) while the loop needs one aborts.
    """

    def __init__(self, controller: SineController, schedule: DemandSchedule, stream: VibrationStream, rotation,
                 gravity, ramp_s: float, measure_periods: int = 4, accel_average_s: float = 0.002,
                 silence_s: float = 0.1, plausible_g: float = 8.0):
        self.controller, self.schedule, self.stream = controller, schedule, stream
        self.rotation = np.asarray(rotation, dtype=float)
        self.gravity = np.asarray(gravity, dtype=float)
        self.ramp_s, self.span = float(ramp_s), measure_periods / schedule.frequency
        self.accel_average_s, self.silence_s = float(accel_average_s), float(silence_s)
        self.plausible = float(plausible_g) * STANDARD_GRAVITY
        self.samples: deque = deque(maxlen=4096)  # (t, accel (3,), gyro (3,))
        self.last_sample = -np.inf
        self.judged_at = -np.inf  # the last judgement without a correction (the stream finished)

    def add_imu(self, t: float, accel, gyro) -> str:
        """One IMU sample at ``t``; returns why it is unusable ("" when it is kept)."""
        a, g = np.asarray(accel, dtype=float), np.asarray(gyro, dtype=float)
        if not (np.isfinite(a).all() and np.isfinite(g).all()):
            return "the platform IMU reported a non-finite value"
        if np.linalg.norm(a) > self.plausible:
            return (f"the platform IMU reported {np.linalg.norm(a):.1f} m/s^2, beyond what this vibration can make "
                    f"({self.plausible:.0f} m/s^2)")
        self.samples.append((float(t), a, g))
        self.last_sample = max(self.last_sample, float(t))
        return ""

    def step(self, now: float, steady_until: float | None) -> LoopStep:
        """At ``now``: correct when a full measurement is in, wait otherwise; ``steady_until``: the end of the
        full-amplitude part (None: until a stop), after which nothing is judged. Once the stream can take no
        correction (``VibrationStream.can_correct``: its ramp-out is near) nothing is corrected, but the abort
        limits and the IMU's silence are still judged (a stop window can still ramp the vibration out)."""
        if now < self.ramp_s or (steady_until is not None and now > steady_until):
            return LoopStep("wait")
        if now - self.last_sample > self.silence_s and now > self.ramp_s + self.silence_s:
            return LoopStep("abort", f"the platform IMU went silent ({now - max(self.last_sample, 0.0):.3f} s "
                                     "without a sample): the delivered vibration cannot be seen")
        first = max(self.schedule.settled_at, self.ramp_s, self.judged_at)
        if now < first + self.span or self.last_sample < now - self.silence_s:
            return LoopStep("wait")
        window = [s for s in self.samples if now - self.span < s[0] <= now]
        if len(window) < MIN_SAMPLES:
            if now > first + self.span + self.silence_s:  # samples arrive, too few to measure: as blind as silence
                return LoopStep("abort", f"the platform IMU's samples are too sparse to measure the vibration "
                                         f"({len(window)} in its last {self.span:.3f} s, {MIN_SAMPLES} needed): the "
                                         "delivered vibration cannot be seen")
            return LoopStep("wait")
        t = np.array([s[0] for s in window])
        accel = np.array([s[1] for s in window])
        gyro = np.array([s[2] for s in window])
        measured = platform_motion(t, accel, gyro, self.schedule.frequency, self.rotation, self.gravity,
                                   self.accel_average_s)
        if not self.stream.can_correct(now):  # judged, not corrected: the next judgement on fresh samples
            self.judged_at = now
            verdict, reason = judge(delivered_figures(measured, self.controller.target,
                                                      self.controller.rotation_scale_m),
                                    self.controller.limits)  # every limit: no correction can follow
            if verdict == "abort":
                return LoopStep("abort", self.controller.with_unit_fault(reason, measured))
            return LoopStep("wait")
        control = self.controller.update(measured)
        if control.verdict == "abort":
            return LoopStep("abort", control.reason, control)
        self.schedule.correct(control.demand, self.stream.splice_time(now))
        return LoopStep("correct", "", control)

def closed_loop_for(robot: Robot, plan: VibrationDecomposition, schedule: DemandSchedule, stream: VibrationStream,
                    identification: VibrationIdentification, rotation, ramp_s: float, gain: float,
                    accel_average_s: float, silence_s: float = 0.1, travel_margin: float = 0.9) -> ClosedLoop:
    """The loop of a started vibration planned with ``identification``'s feed-forward: its platform response
    is the plant estimate, and no unit is asked for a demand its identified response would carry beyond
    ``travel_margin`` of its travel (a resonant unit moves more than its demand). Without an identification
    there is no loop: corrections through the drawing's kinematic map drive the resonant units of a real robot
    past their travel before they converge. ``silence_s``: an IMU sample older than this aborts (ClosedLoop)."""
    estimate = identification.platform_response_at(plan.frequency)
    units = np.abs(identification.unit_response_at(plan.frequency))
    controller = SineController(estimate, target_motion(plan), gain=gain,
                                max_demand_m=travel_margin * robot.vibration_unit.amplitude_max / units,
                                initial_demand=schedule.current)
    return ClosedLoop(controller, schedule, stream, rotation, robot.gravity, ramp_s,
                      accel_average_s=accel_average_s, silence_s=silence_s)
