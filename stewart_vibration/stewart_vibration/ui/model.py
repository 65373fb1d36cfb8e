"""The planning UI's model and server-side checks (pure: numpy and the core library, no rclpy).

What the page shows and what the ``planning_ui`` node refuses before it sends anything to the suite,
computed with the core's own checks:

- pose entry (mm / deg) -> pose (m / rad), R = Rz(yaw) Ry(pitch) Rx(roll) (the paper's eq. 3);
- reachability: the six leg lengths against the stroke, the joint angles against their limits, the
  Jacobian condition number, the first violated limit with its reason (``kinematics.check_pose``);
- a planned path's waypoint count and worst margins to the limits;
- the vibration preview: the decomposition (leg amplitudes, phases 0 or pi, gains), the peak leg
  acceleration against the unit's limit and the reason it is infeasible from the planner's own start check
  (``vibration.settings.start_check``);
- a decimator for the browser streams and a buffer of the full-rate streams
  that feeds the run summary (``vibration_figures.summarize_vibration``) after a vibration.

Every result is JSON-ready (``jsonable``: lists and floats, non-finite numbers as None).
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any

import numpy as np

from ..errors import InvalidInputError, StewartError
from ..kinematics import check_pose, condition_number, inverse_kinematics, joint_angles
from ..kinematics.rotations import rotation_from_rpy, wrap_angle
from ..robot import STANDARD_GRAVITY, Robot
from ..vibration.settings import (
    VIBRATION_KEYS,
    default_settings,
    plan_vibration,
    settings_reason,
    start_check,
    start_refusal,
)
from ..vibration.waveform import acceleration_from_displacement

CONVENTION = ("pose [x, y, z, roll, pitch, yaw] of the platform frame in the base frame; "
              "R = Rz(yaw) Ry(pitch) Rx(roll) (paper eq. 3); x, y, z in mm, angles in deg")
POSE_FIELDS = ("x_mm", "y_mm", "z_mm", "roll_deg", "pitch_deg", "yaw_deg")
POSITION_LIMIT_MM = 1000.0  # entries beyond these are typos, refused before any check
ANGLE_LIMIT_DEG = 360.0
# The planner's vibration parameters the page sets (vibration_planner SetParameters)


def stream_defaults(robot: Robot) -> dict:
    """The planner's streaming settings at their defaults: used until the planner's own values are known."""
    return {k: v for k, v in default_settings(robot).items() if k not in VIBRATION_KEYS}


def jsonable(value):
    """numpy -> plain Python, recursively; NaN and +-inf -> None (JSON has neither)."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def error_info(exc: Exception) -> dict:
    """A typed core error as the page shows it: type, message, leg (1..6 or None)."""
    return {"type": type(exc).__name__, "message": str(exc), "leg": getattr(exc, "leg", None)}


def _number(fields: dict, name: str, low: float = -math.inf, high: float = math.inf) -> float:
    value = fields.get(name) if isinstance(fields, dict) else None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InvalidInputError(f"{name} must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise InvalidInputError(f"{name} must be finite, got {value}")
    if not low <= value <= high:
        raise InvalidInputError(f"{name} = {value:g} is outside [{low:g}, {high:g}]")
    return value


# -- poses -----------------------------------------------------------------------------------------
def pose_from_fields(fields: dict) -> np.ndarray:
    """{x_mm, y_mm, z_mm, roll_deg, pitch_deg, yaw_deg} -> pose (m, rad); InvalidInputError saying which field."""
    position = [_number(fields, n, -POSITION_LIMIT_MM, POSITION_LIMIT_MM) * 1e-3 for n in POSE_FIELDS[:3]]
    angles = [math.radians(_number(fields, n, -ANGLE_LIMIT_DEG, ANGLE_LIMIT_DEG)) for n in POSE_FIELDS[3:]]
    return np.array(position + angles)


def pose_fields(pose) -> dict:
    """pose (m, rad) -> the page's fields (mm, deg)."""
    pose = np.asarray(pose, dtype=float)
    values = np.concatenate([pose[:3] * 1e3, np.degrees(pose[3:])])
    return {name: float(v) for name, v in zip(POSE_FIELDS, values, strict=True)}


def reachability(robot: Robot, pose) -> dict:
    """Is ``pose`` reachable? Leg lengths vs stroke (mm), joint angles vs limits (deg), condition number,
    and the first violated limit with its reason (check_pose's typed error), or error None."""
    pose = np.asarray(pose, dtype=float)
    lim = robot.limits
    lengths = inverse_kinematics(robot, pose, check_limits=False)
    universal, spherical = joint_angles(robot, pose)
    cond = float(condition_number(robot, pose))
    try:
        check_pose(robot, pose)
        error = None
    except StewartError as exc:
        error = error_info(exc)
    margins = np.minimum(lengths - lim.stroke_min, lim.stroke_max - lengths)
    return jsonable({
        "pose": pose, "fields": pose_fields(pose), "reachable": error is None, "error": error,
        "leg_lengths_mm": lengths * 1e3, "stroke_mm": [lim.stroke_min * 1e3, lim.stroke_max * 1e3],
        "stroke_margin_mm": margins * 1e3,
        "universal_deg": np.degrees(universal), "universal_max_deg": math.degrees(lim.universal_joint_max),
        "spherical_deg": np.degrees(spherical), "spherical_max_deg": math.degrees(lim.spherical_joint_max),
        "condition_number": cond, "condition_number_max": lim.condition_number_max,
    })


def path_margins(robot: Robot, poses) -> dict:
    """Waypoint count and the worst margins to the limits along a path [n, 6] (as plan_path returns it)."""
    poses = np.asarray(poses, dtype=float).reshape(-1, 6)
    if poses.shape[0] == 0:
        return {"waypoints": 0}
    lim = robot.limits
    lengths = inverse_kinematics(robot, poses, check_limits=False)
    universal, spherical = joint_angles(robot, poses)
    cond = condition_number(robot, poses)
    stroke = np.minimum(lengths - lim.stroke_min, lim.stroke_max - lengths)
    margins = {  # name -> (margin, its unit, the margin as a fraction of the limit's scale)
        "stroke": (stroke.min() * 1e3, "mm", stroke.min() / (0.5 * (lim.stroke_max - lim.stroke_min))),
        "universal joint": (math.degrees(lim.universal_joint_max - universal.max()), "deg",
                            1 - universal.max() / lim.universal_joint_max),
        "spherical joint": (math.degrees(lim.spherical_joint_max - spherical.max()), "deg",
                            1 - spherical.max() / lim.spherical_joint_max),
        "condition number": (lim.condition_number_max - cond.max(), "", 1 - cond.max() / lim.condition_number_max),
    }
    worst = min(margins, key=lambda k: margins[k][2])
    at = np.unravel_index(int(np.argmin(stroke)), stroke.shape)
    return jsonable({
        "waypoints": int(poses.shape[0]), "start": pose_fields(poses[0]), "goal": pose_fields(poses[-1]),
        "stroke_margin_mm": margins["stroke"][0], "stroke_margin_at": {"waypoint": int(at[0]), "leg": int(at[1]) + 1},
        "universal_margin_deg": margins["universal joint"][0], "spherical_margin_deg": margins["spherical joint"][0],
        "condition_number_max": float(cond.max()), "condition_number_limit": lim.condition_number_max,
        "worst": {"limit": worst, "margin": margins[worst][0], "unit": margins[worst][1],
                  "fraction": margins[worst][2]},
    })


def platform_points(robot: Robot, pose) -> np.ndarray:
    """Platform hinge centres A_i in the base frame [6, 3] (m) at ``pose`` (for the robot view)."""
    pose = np.asarray(pose, dtype=float)
    return pose[:3] + robot.platform_hinges @ rotation_from_rpy(pose[3:]).T


def pose_error(pose, target) -> tuple[float, float]:
    """(max |position error| m, max |angle error| rad) of ``pose`` against ``target`` (angles wrapped)."""
    err = np.asarray(pose, float) - np.asarray(target, float)
    angles = wrap_angle(err[3:])
    return float(np.abs(err[:3]).max()), float(np.abs(angles).max())


# -- vibration -----------------------------------------------------------------------------------
def vibration_from_fields(fields: dict) -> dict:
    """The page's vibration fields -> the planner's parameters (SI), checked for form only (the planner
    and ``vibration_preview`` check the values). Fields: direction [3], frame, mode ("acceleration" |
    "amplitude"), acceleration_g, amplitude_um, frequency_hz, phase_deg, duration_s, ramp_s.
    In acceleration mode amplitude_m = 0 (the planner then uses acceleration_g); in amplitude mode
    acceleration_g is not sent."""
    if not isinstance(fields, dict):
        raise InvalidInputError("vibration settings must be an object")
    direction = fields.get("direction")
    if not isinstance(direction, list) or len(direction) != 3:
        raise InvalidInputError(f"direction must be 3 numbers, got {direction!r}")
    direction = [_number({"direction": v}, "direction") for v in direction]
    frame = fields.get("frame")
    if frame not in ("platform", "base"):
        raise InvalidInputError(f"frame must be 'platform' or 'base', got {frame!r}")
    mode = fields.get("mode", "acceleration")
    if mode not in ("acceleration", "amplitude"):
        raise InvalidInputError(f"mode must be 'acceleration' or 'amplitude', got {mode!r}")
    settings = {"direction": direction, "frame": frame}
    if mode == "acceleration":
        settings["amplitude_m"] = 0.0
        settings["acceleration_g"] = _number(fields, "acceleration_g")
    else:
        settings["amplitude_m"] = _number(fields, "amplitude_um") * 1e-6
    settings["frequency_hz"] = _number(fields, "frequency_hz")
    settings["phase_rad"] = math.radians(_number(fields, "phase_deg"))
    settings["duration_s"] = _number(fields, "duration_s")
    settings["ramp_s"] = _number(fields, "ramp_s")
    return settings


def range_reason(settings: dict, ranges: dict) -> str | None:
    """The first parameter outside the planner's declared range {name: (low, high)}, said as a reason."""
    for name, (low, high) in ranges.items():
        value = settings.get(name)
        if isinstance(value, float) and not low <= value <= high:
            return f"{name} = {value:g} is outside the planner's range [{low:g}, {high:g}]"
    return None


def vibration_preview(robot: Robot, pose, settings: dict, ranges=None) -> dict:
    """What the planner would run at ``pose`` with ``settings`` (its full parameter set): the decomposition
    (leg amplitudes um, phases rad, gains), the peak leg acceleration (g) against the unit's limit, and
    ``feasible`` / ``reason`` from the planner's own start check (``vibration.settings.start_check``: the
    settings, the decomposition's limits, the first streamed window with its ramp, a stop window) after the
    planner's declared ``ranges`` {name: (low, high)}."""
    unit = robot.vibration_unit
    out: dict[str, Any] = {"feasible": False, "reason": None, "limits": {
        "acceleration_max_g": unit.acceleration_max / STANDARD_GRAVITY, "amplitude_max_um": unit.amplitude_max * 1e6,
        "velocity_max_mm_s": unit.velocity_max * 1e3, "frequency_band_hz": [unit.frequency_min, unit.frequency_max]}}
    s = settings
    try:
        plan = plan_vibration(robot, pose, s, check_limits=False)
    except StewartError as exc:
        out["reason"] = f"invalid vibration ({type(exc).__name__}): {exc}"
        return jsonable(out)
    omega = 2 * math.pi * plan.frequency
    out.update({
        "amplitude_um": plan.amplitude * 1e6,
        "acceleration_g": acceleration_from_displacement(plan.amplitude, plan.frequency),
        "frequency_hz": plan.frequency, "phase_rad": plan.phase, "direction_base": plan.direction,
        "gains": plan.gains, "leg_amplitudes_um": plan.leg_amplitudes * 1e6, "leg_phases_rad": plan.leg_phases,
        "peak_leg_acceleration_g": plan.peak_leg_acceleration / STANDARD_GRAVITY,
        "peak_leg_velocity_mm_s": plan.leg_amplitudes * omega * 1e3, "equations": plan.equations(),
    })
    reason = range_reason(s, ranges or {}) or settings_reason(robot, s)
    if reason:
        out["reason"] = reason
        return jsonable(out)
    try:
        start_check(robot, pose, s)
    except StewartError as exc:
        out["reason"] = start_refusal(exc, s)
    else:
        out["feasible"] = True
    return jsonable(out)


# -- streams ---------------------------------------------------------------------------------------
class Decimator:
    """Keeps every ``every``-th sample of a stream across batches (the browser gets rate / every)."""

    def __init__(self, every: int):
        self.every = max(int(every), 1)
        self.phase = 0

    def take(self, n: int) -> np.ndarray:
        """Indices to keep of the next ``n`` samples."""
        first = (-self.phase) % self.every
        self.phase = (self.phase + n) % self.every
        return np.arange(first, n, self.every)


class StreamBuffer:
    """The last ``keep_s`` seconds (by stamp) of one full-rate stream: stamps [n] and rows [n, k]."""

    def __init__(self, keep_s: float):
        self.keep_s = keep_s
        self.chunks: deque = deque()

    def add(self, stamps: np.ndarray, rows: np.ndarray) -> None:
        """Append a batch: stamps [n] (s) and rows [n, k]; drops chunks older than ``keep_s`` before the latest."""
        if len(stamps):
            self.chunks.append((np.asarray(stamps, float), np.asarray(rows, float)))
            latest = self.chunks[-1][0][-1]
            while len(self.chunks) > 1 and self.chunks[0][0][-1] < latest - self.keep_s:
                self.chunks.popleft()

    def arrays(self, width: int) -> tuple[np.ndarray, np.ndarray]:
        """All kept stamps [n] (s) and rows [n, ``width``] in order (empty [0, width] arrays if none)."""
        if not self.chunks:
            return np.empty(0), np.empty((0, width))
        return np.concatenate([c[0] for c in self.chunks]), np.concatenate([c[1] for c in self.chunks])

    def span(self) -> tuple[float, float] | None:
        """(first, last) kept stamp (s), or None if empty."""
        return (self.chunks[0][0][0], self.chunks[-1][0][-1]) if self.chunks else None


def run_summary(robot: Robot, joints: StreamBuffer, pose: StreamBuffer, forces: StreamBuffer, nominal_pose,
                parameters: dict, t0: float, ended: float) -> dict:
    """The run summary of one vibration from the live buffers (what ``stewart-vibration run`` reports from the
    MCAP): platform amplitude and direction error (of ``pose``: the page passes the
    controller's pose estimate), leg amplitudes, phases and frequency, the
    leg-force model error. ``parameters``: the settings that ran (from the vibrate goal's plan); ``ended``: the
    sim time the units came to rest (a vibration until stop is summarised over what ran)."""
    from ..analysis.vibration_figures import summarize_vibration

    jt, jrows = joints.arrays(24)
    pt, prows = pose.arrays(6)
    ft, frows = forces.arrays(6)
    params = dict(parameters)
    params["duration_s"] = ended - t0 if not params.get("duration_s") else min(params["duration_s"], ended - t0)
    signals = {"pose": (pt, prows), "joints": (jt, {"position": jrows[:, :12], "effort": jrows[:, 12:]}),
               "force_estimate": (ft, {"effort": frows}), "vibration_starts": np.array([t0])}
    s = summarize_vibration(robot, signals, np.asarray(nominal_pose, float), params, t0)
    force = s.get("force") or {}
    return jsonable({
        "t0_s": t0, "ended_s": ended, "frequency_hz": s["frequency_hz"], "window_s": s["window_s"],
        "planned_amplitude_um": s["planned_amplitude_m"] * 1e6,
        "measured_amplitude_um": s["measured_amplitude_m"] * 1e6,
        "amplitude_error_pct": s["amplitude_error"] * 100, "direction_error_deg": s["direction_error_deg"],
        "leg_amplitude_um": np.asarray(s["leg_amplitude_m"]) * 1e6,
        "leg_amplitude_expected_um": np.asarray(s["leg_amplitude_expected_m"]) * 1e6,
        "leg_phase_error_deg": s["leg_phase_error_deg"], "leg_frequency_spread_hz": s["leg_frequency_spread_hz"],
        "active_duration_s": s["active_duration_s"],
        "force_error_worst_leg_pct": force["worst_leg_vs_largest_amplitude"] * 100 if force else None,
        "force_rms_error_n": force.get("rms_error_n"),
    })
