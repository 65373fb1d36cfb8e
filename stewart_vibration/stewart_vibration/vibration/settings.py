"""The vibration planner's settings: the one source of their names, defaults, ranges and checks.

The planner node declares its streaming parameters (``STREAM_KEYS``) from ``parameters``; a vibration goal
(the scenario files' vibrate steps, ``runtime.scenario``, and the planning UI) carries the ``VIBRATION_KEYS``;
and the run summary (``analysis.vibration_figures``) judges a vibration against the settings the planner reports
it ran (the goal's and its parameters, with the plan), never against defaults filled in again.

``start_check`` is what the planner does before it starts (and the UI's preview repeats): the settings
check, the decomposition at the pose with the unit's limits, the first streamed window (ramp-in
included) and a stop window at full amplitude against the unit's limits. It returns the plan and the
stream to run, or raises the typed error whose ``start_refusal`` text both say.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import cast

import numpy as np

from ..errors import InvalidInputError, StewartError, VibrationLimitError
from ..input_checks import safe_norm
from ..robot import Robot
from .compensation import compensated_demands
from .decompose import FRAMES, VibrationDecomposition, decompose_vibration
from .demand_schedule import DemandSchedule
from .feasibility import check_command_limits
from .leg_demands import decomposition_demands
from .streaming import StreamSettings, VibrationStream, VibrationWindow
from .unit_identification import VibrationIdentification

MAX_WINDOW_SAMPLES = 100_000  # one message; the emulator refuses windows reaching > 30 s ahead anyway


@dataclass(frozen=True)
class Parameter:
    """One numeric planner setting: default, declared range [low, high] and description (SI units)."""

    default: float
    low: float
    high: float
    description: str


# the streaming's timing: the planner node's own parameters (robot-independent; parameters.tables declares them)
STREAM_PARAMETERS = {
    "lookahead_s": Parameter(2.0, 0.05, 60.0, "vibration carried by each streamed window before its ramp-out "
                             "tail, s"),
    "window_period_s": Parameter(0.5, 0.01, 30.0, "period between streamed windows, s (< lookahead_s)"),
    "sample_period_s": Parameter(0.001, 1e-4, 0.05, "sample spacing in a window, s"),
    "lead_s": Parameter(0.3, 0.0, 2.0, "streamed windows start this far ahead of now, s of wall time (more "
                        "sim seconds when the sim clock runs faster than real time)"),
    "start_lead_s": Parameter(1.0, 0.0, 5.0, "the vibration starts (t0) this far after the start call, s of "
                              "wall time (>= lead_s; more sim seconds when the sim clock runs faster than real "
                              "time)"),
    "max_lookahead_s": Parameter(5.0, 0.1, 30.0, "a finite vibration ending within this time is sent whole in "
                                 "one window, s (the emulator accepts windows reaching up to 30 s ahead)"),
    "pose_timeout_s": Parameter(1.0, 0.01, 60.0, "start needs a pose estimate received within this time, s "
                                "of wall time"),
}


def parameters(robot: Robot) -> dict[str, Parameter]:
    """The planner's numeric settings with their defaults and declared ranges (the frequency range is the
    vibration unit's band of ``robot``).

    Args:
        robot: the robot; ``robot.vibration_unit`` gives frequency_min / frequency_max (Hz).

    Returns:
        {name: Parameter(default, low, high, description)} for every numeric setting (SI units: m, g,
        Hz, rad, s).
    """
    unit = robot.vibration_unit
    return {
        "amplitude_m": Parameter(0.0, 0.0, 0.01, "platform displacement amplitude, m (0 = use acceleration_g)"),
        "acceleration_g": Parameter(0.3, 0.0, 10.0, "peak platform acceleration, g (used when amplitude_m = 0)"),
        "frequency_hz": Parameter(35.0, unit.frequency_min, unit.frequency_max,
                                  "vibration frequency, Hz (the vibration unit's band)"),
        "phase_rad": Parameter(0.0, -2 * math.pi, 2 * math.pi, "phase of the platform vibration, rad"),
        "duration_s": Parameter(0.0, 0.0, 86400.0, "vibration duration incl. ramps, s (0 = until stop; else "
                                "at least two ramps)"),
        "ramp_s": Parameter(0.2, 0.01, 10.0, "ramp-in / ramp-out time, s"),
        **STREAM_PARAMETERS,
    }


DEFAULT_DIRECTION = (0.0, 0.0, 1.0)  # the tibia axis (platform z)
DEFAULT_FRAME = "platform"
# every setting, in the order the planner declares and reports them
SETTINGS = ("direction", "frame", "amplitude_m", "acceleration_g", "frequency_hz", "phase_rad", "duration_s", "ramp_s",
            "lookahead_s", "window_period_s", "sample_period_s", "lead_s", "start_lead_s", "max_lookahead_s",
            "pose_timeout_s")
# what a vibration is (a scenario's vibrate step, the planning UI, a vibration goal); the rest is the
# streaming's timing: the planner's own parameters
VIBRATION_KEYS = SETTINGS[:8]
STREAM_KEYS = SETTINGS[8:]


def default_settings(robot: Robot) -> dict:
    """Every setting at its default (what the planner runs with when nothing is set).

    Args:
        robot: the robot (for the numeric defaults of ``parameters``).

    Returns:
        {name: value} for every name of SETTINGS: "direction" [0, 0, 1] (the tibia axis), "frame"
        "platform" and the numeric defaults.
    """
    values = {name: p.default for name, p in parameters(robot).items()}
    return {"direction": list(DEFAULT_DIRECTION), "frame": DEFAULT_FRAME, **values}


def duration_reason(duration_s: float, ramp_s: float) -> str | None:
    """The one rule for a vibration's length: duration_s = 0 (until stop) or at least two ramps (ramp-in and
    ramp-out; the steady part may be empty). The reason it is broken, or None.

    Args:
        duration_s: vibration duration including the ramps (s; 0 = until stop).
        ramp_s: ramp-in / ramp-out time (s).

    Returns:
        The reason text, or None if the rule holds.
    """
    if duration_s != 0 and not duration_s >= 2 * ramp_s:
        return f"duration_s {duration_s} must be 0 (until stop) or >= 2 ramp_s = {2 * ramp_s}"
    return None


def settings_reason(robot: Robot, s: dict) -> str | None:
    """The reason the planner settings ``s`` (every name of SETTINGS) are invalid, or None. Never raises
    for values of the parameters' types (any double, a double array of any length, any string).

    Args:
        robot: the robot; ``robot.vibration_unit`` gives the frequency band (Hz).
        s: {name: value} for every name of SETTINGS (direction 3 values, frame, the rest in SI units).

    Returns:
        The first reason found (direction: 3 finite values with a non-zero norm that does not overflow;
        frame, finiteness, frequency band, signs, window size, amplitude / acceleration, ramps and duration,
        streaming timing, sampling, then every declared range of ``parameters``), or None if valid.
    """
    unit = robot.vibration_unit
    direction = np.asarray(list(s["direction"]), dtype=float)
    if direction.shape != (3,) or not np.isfinite(direction).all() or safe_norm(direction) < 1e-9:
        return f"direction must be 3 finite values, not all zero; got {list(s['direction'])}"
    if not math.isfinite(safe_norm(direction)):
        return f"direction {list(s['direction'])} is too long: its length overflows (only its direction counts)"
    if s["frame"] not in FRAMES:
        return f"frame must be one of {list(FRAMES)}, got {s['frame']!r}"
    for name, value in s.items():
        if name not in ("direction", "frame") and not math.isfinite(value):
            return f"{name} must be finite, got {value}"
    if not unit.frequency_min <= s["frequency_hz"] <= unit.frequency_max:
        return (f"frequency_hz {s['frequency_hz']} is outside the vibration unit's band "
                f"[{unit.frequency_min}, {unit.frequency_max}] Hz")
    for name in ("sample_period_s", "lookahead_s", "window_period_s", "max_lookahead_s", "pose_timeout_s"):
        if s[name] <= 0:
            return f"{name} must be > 0, got {s[name]}"
    for name in ("lead_s", "start_lead_s", "duration_s"):
        if s[name] < 0:
            return f"{name} must be >= 0, got {s[name]}"
    samples = (max(s["max_lookahead_s"], s["lookahead_s"] + s["ramp_s"]) + s["start_lead_s"]) / s["sample_period_s"]
    if samples > MAX_WINDOW_SAMPLES:
        return (f"a window could hold {samples:.0f} samples (max_lookahead_s / sample_period_s); at most "
                f"{MAX_WINDOW_SAMPLES}: raise sample_period_s or lower max_lookahead_s")
    if s["amplitude_m"] < 0:
        return f"amplitude_m must be >= 0, got {s['amplitude_m']}"
    if s["amplitude_m"] == 0 and s["acceleration_g"] <= 0:
        return "acceleration_g must be > 0 when amplitude_m = 0"
    if s["ramp_s"] <= 0:
        return f"ramp_s must be > 0, got {s['ramp_s']}"
    if reason := duration_reason(s["duration_s"], s["ramp_s"]):
        return reason
    if s["lookahead_s"] <= s["window_period_s"]:
        return (f"lookahead_s {s['lookahead_s']} must exceed window_period_s {s['window_period_s']} (the next "
                "window must arrive before the last one's ramp-out)")
    if s["start_lead_s"] < s["lead_s"]:
        return f"start_lead_s {s['start_lead_s']} must be >= lead_s {s['lead_s']} (the first window starts at t0)"
    if s["max_lookahead_s"] < s["lookahead_s"]:
        return f"max_lookahead_s {s['max_lookahead_s']} must be >= lookahead_s {s['lookahead_s']}"
    if s["sample_period_s"] * s["frequency_hz"] > 0.1:
        return (f"sample_period_s {s['sample_period_s']} is too coarse for {s['frequency_hz']} Hz "
                "(need >= 10 samples per period)")
    for name, p in parameters(robot).items():  # what the planner's parameter descriptors enforce, for every caller
        if not p.low <= s[name] <= p.high:
            return f"{name} {s[name]} is outside its range [{p.low:g}, {p.high:g}]"
    return None


def plan_vibration(robot: Robot, pose, s: dict, check_limits: bool = True, method: str = "exact"
                   ) -> VibrationDecomposition:
    """The decomposition the settings ``s`` ask for at ``pose`` [6]: amplitude_m if > 0, else acceleration_g;
    ``method`` "exact" (what the planner streams) or "linear" (gains k = J s, what the run summary judges the
    legs against).

    Args:
        robot: the robot.
        pose: nominal platform pose [6] [x, y, z, roll, pitch, yaw] (m, rad), base frame.
        s: the settings; uses direction, frame, amplitude_m (m), acceleration_g (g), frequency_hz (Hz) and
            phase_rad (rad).
        check_limits: check the vibration against the unit's, stroke and joint limits.
        method: "exact" or "linear".

    Returns:
        The VibrationDecomposition (one period of samples, base frame).

    Raises:
        InvalidInputError: a malformed direction, frame, pose or method; a non-finite or non-positive
            frequency, amplitude or acceleration.
        VibrationLimitError: with ``check_limits``, the frequency is outside the unit's band or a leg's
            peak amplitude or acceleration exceeds the unit's limit.
        UnreachablePoseError, StrokeLimitError, JointLimitError: with ``check_limits``, the pose or the
            vibration's extreme poses cannot be taken.
    """
    use_amplitude = s["amplitude_m"] > 0
    return decompose_vibration(
        robot, pose, list(s["direction"]), amplitude=s["amplitude_m"] if use_amplitude else None,
        acceleration_g=None if use_amplitude else s["acceleration_g"], frequency=s["frequency_hz"],
        phase=s["phase_rad"], frame=s["frame"], method=method, check_limits=check_limits)


def same_seconds(seconds: float) -> float:
    """A wall-time margin at real time: as many sim seconds.

    Args:
        seconds: a wall-time margin (s).

    Returns:
        ``seconds`` unchanged (sim s).
    """
    return seconds


def stream_settings(s: dict, wall_margin=same_seconds) -> StreamSettings:
    """The streaming's timing from the settings (duration_s 0 = until stop). ``wall_margin`` turns the
    wall-time margins lead_s and start_lead_s into sim seconds (``runtime.sim_clock.ClockRate.wall_margin``
    faster than real time): a finite vibration sent whole may reach that much further ahead.

    Args:
        s: the settings; uses duration_s, ramp_s, sample_period_s, lookahead_s, lead_s, start_lead_s and
            max_lookahead_s (s).
        wall_margin: maps a wall-time margin (s) to sim seconds.

    Returns:
        StreamSettings (sim s): duration None for duration_s 0, lead_s through ``wall_margin``, and
        max_lookahead_s plus the extra sim seconds ``wall_margin`` adds to start_lead_s.
    """
    start_lead = wall_margin(s["start_lead_s"])
    return StreamSettings(duration=s["duration_s"] if s["duration_s"] > 0 else None, ramp_s=s["ramp_s"],
                          sample_period_s=s["sample_period_s"], lookahead_s=s["lookahead_s"],
                          lead_s=wall_margin(s["lead_s"]),
                          max_lookahead_s=s["max_lookahead_s"] + start_lead - s["start_lead_s"])


@dataclass(frozen=True)
class StartPlan:
    """What a start runs: the decomposition, its stream (the first window already taken), that window and
    t0's lead over the start call (sim s)."""

    plan: VibrationDecomposition
    stream: VibrationStream
    first: VibrationWindow
    start_lead: float
    compensation: str = "uncompensated"  # how the legs' demands were made (compensation.compensated_demands)
    schedule: DemandSchedule | None = None  # the complex demands the stream samples (feed-forward, closed loop)
    compensated: bool = False  # the demands are the identification's feed-forward


def start_check(robot: Robot, pose, s: dict, wall_margin=same_seconds,
                identification: VibrationIdentification | None = None, closed_loop: bool = False) -> StartPlan:
    """Everything the planner checks before it starts a vibration at ``pose`` with the settings ``s``.

    The settings (``settings_reason``), the decomposition with the unit's and the stroke limits, the first
    window (sent at the start call, start_lead_s before t0, ramp-in included) and, for a vibration that
    is streamed, a stop window at full amplitude against the unit's limits. ``wall_margin`` turns the
    wall-time leads into sim seconds (see ``stream_settings``).

    With ``identification`` (vibration.unit_identification) made at this pose and covering the frequency, the
    legs' demands are its feed-forward (vibration.compensation); otherwise the decomposition's own legs, and
    the StartPlan's ``compensation`` says why. With ``closed_loop`` the demands are complex ones in a
    DemandSchedule (the StartPlan's ``schedule``) whatever the compensation, and the vibration is streamed in
    windows however short, so a correction can go into the next one.

    Returns:
        The StartPlan; its stream has sent the first window (times relative to t0).

    Raises:
        InvalidInputError: the settings are invalid (the reason of ``settings_reason``).
        VibrationLimitError, StrokeLimitError, StewartError: the vibration is infeasible.
    """
    if reason := settings_reason(robot, s):
        raise InvalidInputError(reason)
    plan = plan_vibration(robot, pose, s, check_limits=True)
    start_lead = wall_margin(s["start_lead_s"])
    demands, compensation = compensated_demands(identification, plan)
    compensated = demands is not None
    if demands is None and closed_loop:  # the loop corrects complex demands: the decomposition's, first order
        demands = decomposition_demands(plan)

    def schedule() -> DemandSchedule | None:
        return None if demands is None else DemandSchedule(demands, plan.frequency)

    settings = stream_settings(s, wall_margin)
    if closed_loop:  # streamed in windows whatever its length: a correction goes into the next one
        settings = replace(settings, max_lookahead_s=settings.lookahead_s)
    demand_schedule = schedule()
    stream = VibrationStream(robot, plan, settings, demands=demand_schedule)
    first = cast(VibrationWindow, stream.next_window(-start_lead))  # a new stream always has a first window
    check_command_limits(robot.vibration_unit, first.times, first.position, first.velocity, first.acceleration)
    if not stream.finished:  # the ramps and the stop ramp too: one stop window at full amplitude
        probe = VibrationStream(robot, plan, stream.settings, demands=schedule())
        probe.next_window(-start_lead)
        stop = probe.stop_window(s["ramp_s"])
        if stop is not None:
            check_command_limits(robot.vibration_unit, stop.times, stop.position, stop.velocity, stop.acceleration)
    return StartPlan(plan, stream, first, start_lead, compensation, demand_schedule, compensated)


def start_refusal(exc: StewartError, s: dict) -> str:
    """How the planner (and the UI's preview) says why ``start_check`` refused: the error's type and text.

    Args:
        exc: the error ``start_check`` raised.
        s: the settings (ramp_s (s) is named for a VibrationLimitError).

    Returns:
        "infeasible vibration (<type>): <text>", with a hint on ramp_s for a VibrationLimitError.
    """
    if isinstance(exc, VibrationLimitError):
        return (f"infeasible vibration ({type(exc).__name__}): {exc} (with the ramps of ramp_s {s['ramp_s']} s; a "
                "longer ramp_s lowers the peak acceleration)")
    return f"infeasible vibration ({type(exc).__name__}): {exc}"
