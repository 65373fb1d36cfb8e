"""An independent check of a recorded run against the robot's limits (pure: arrays in, figures out).

Its job is to judge the emulator, so it shares none of the emulator's acceptance code: it reads the limits
from ``robot.limits`` and ``robot.vibration_unit`` (config/robot.yaml) and recomputes every figure from
the recorded states:

- stroke: every hinge-to-hinge length leg_i + vib_i of ``legs/joint_states`` in [stroke_min, stroke_max]
  (within ``STROKE_TOLERANCE_M``);
- strut velocity and acceleration: differences of the leg_i lengths over their header stamps (velocity
  from neighbouring states; acceleration from second differences over ``STRUT_BASELINE`` states, 10 ms
  at 500 Hz, so that position noise of 1e-9 m gives at most 4e-5 m/s^2). The acceleration limit is the strut
  drives' (robot.yaml: every commanded strut motion is checked against it), so it is judged on the struts'
  own motion: the lengths averaged twice over ``DRIVE_AVERAGE`` states (50 ms, zeros at 20, 40 and 60 Hz:
  the units' reaction shaking a strut's servo in the therapy band is 1/60 of itself or less there, while a
  move's acceleration, over hundreds of milliseconds, passes whole);
- vibration units: |vib_i| against amplitude_max, its velocity and acceleration from neighbouring states
  (a sinusoid at f sampled every dt is underestimated by 2 (1 - cos w dt) / (w dt)^2: 1.6 % at 35 Hz,
  16 % at 120 Hz, 500 Hz states);
- universal and spherical joint angles and the Jacobian's condition number at every recorded true
  platform pose (``ground_truth/platform_pose``), from the robot's hinge points;
- finiteness of every recorded position, velocity, effort and pose;
- time: ``/clock`` never goes back and the joint states' stamps increase.

A rate counts as a violation when it exceeds its limit by more than ``TOLERANCE`` (relative: the
differentiation noise), a displacement, angle or condition number by more than ``MEASURED_TOLERANCE``;
no difference is taken across a gap in the
states (a lost sample is not motion).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..kinematics.jacobian import condition_number
from ..kinematics.rotations import rotation_from_rpy
from ..robot import Robot

STRUT_BASELINE = 5  # states on each side of a strut acceleration sample
DRIVE_AVERAGE = 25  # states in each of the two moving averages the strut acceleration is judged after
STRUT_SUPPORT = STRUT_BASELINE + DRIVE_AVERAGE - 1  # states on each side a strut acceleration sample reads
TOLERANCE = 0.02  # relative excess over a rate limit that is still differentiation noise
MEASURED_TOLERANCE = 1e-6  # relative, for figures measured or computed from poses (displacement, angles, conditioning)
STROKE_TOLERANCE_M = 1e-6  # a length is measured, not differentiated: 1 um is the servo's following error
GAP_FACTOR = 1.5  # a step longer than this many median state periods is a gap (not differentiated)
POSE_SLAB = 50_000  # poses whose joint angles and condition numbers are computed together


@dataclass(frozen=True)
class LimitFigure:
    """One checked figure: its worst value over the run, its limit (same unit), where and when the worst
    was, and how many samples exceeded the limit beyond the tolerance."""

    name: str
    unit: str
    worst: float
    limit: float
    time_s: float | None = None
    leg: int | None = None
    violations: int = 0
    low_limit: float | None = None  # a two-sided figure (the stroke): its lower limit
    least: float | None = None  # and its lowest value

    @property
    def violated(self) -> bool:
        """Whether a sample exceeded the limit by more than the tolerance (or was not finite)."""
        return self.violations > 0

    def line(self) -> str:
        """The figure as the run summary prints it, e.g. "strut velocity 0.0100 m/s (leg 1 at 7.821 s),
        limit 0.02 m/s"."""
        unit = f" {self.unit}" if self.unit else ""
        place = ", ".join(x for x in (f"leg {self.leg}" if self.leg else "",
                                      f"at {self.time_s:.3f} s" if self.time_s is not None else "") if x)
        span = f"{self.least:.6g}..{self.worst:.6g}" if self.least is not None else f"{self.worst:.6g}"
        limit = f"{self.low_limit:g}..{self.limit:g}" if self.low_limit is not None else f"{self.limit:g}"
        beyond = f"; {self.violations} samples beyond it" if self.violations else ""
        return f"{self.name} {span}{unit}{f' ({place})' if place else ''}, limit {limit}{unit}{beyond}"


def _worst(values: np.ndarray, times: np.ndarray, limit: float, name: str, unit: str,
           tolerance: float = TOLERANCE) -> LimitFigure:
    """The largest of ``values`` [n, k] (times [n]) against ``limit`` (relative ``tolerance``); NaN counts as a
    violation."""
    if values.size == 0:
        return LimitFigure(name, unit, 0.0, limit)
    flat = np.where(np.isfinite(values), values, np.inf)
    index = np.unravel_index(int(np.argmax(flat)), flat.shape)
    worst = float(values[index])
    bad = int(np.count_nonzero(~(values <= limit * (1 + tolerance))))
    leg = int(index[1]) + 1 if values.ndim == 2 else None
    return LimitFigure(name, unit, worst, limit, float(times[index[0]]), leg, bad)


def stroke_excess(hinge: np.ndarray, low: float, high: float) -> np.ndarray:
    """How far (m) each hinge-to-hinge length lies outside [low, high] (negative inside; inf if not finite)."""
    finite = np.where(np.isfinite(hinge), hinge, np.nan)
    return np.maximum(np.nan_to_num(low - finite, nan=np.inf), np.nan_to_num(finite - high, nan=np.inf))


def _stroke(hinge: np.ndarray, t: np.ndarray, low: float, high: float) -> LimitFigure:
    """The hinge-to-hinge lengths [n, 6] (m) against [low, high] (m), STROKE_TOLERANCE_M either side."""
    if hinge.size == 0:
        return LimitFigure("stroke", "m", 0.0, high, low_limit=low, least=0.0)
    finite = np.where(np.isfinite(hinge), hinge, np.nan)
    excess = stroke_excess(hinge, low, high)
    index = np.unravel_index(int(np.argmax(excess)), excess.shape)
    bad = int(np.count_nonzero(~(excess <= STROKE_TOLERANCE_M)))
    return LimitFigure("stroke", "m", float(np.nanmax(finite)), high, float(t[index[0]]), int(index[1]) + 1, bad,
                       low, float(np.nanmin(finite)))


def _uniform_steps(t: np.ndarray) -> tuple[np.ndarray, float]:
    """(dt [n-1], median period) with steps across gaps or backwards set to NaN."""
    dt = np.diff(t)
    positive = dt[dt > 0]
    period = float(np.median(positive)) if positive.size else np.nan
    dt = np.where((dt > 0) & (dt <= GAP_FACTOR * period), dt, np.nan)
    return dt, period


def rates(t: np.ndarray, x: np.ndarray, baseline: int = 1,
          first: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Velocity and acceleration of ``x`` [n, k] sampled at ``t`` [n] (s), never across a gap.

    ``first``: the samples before it only complete the differences of the ones from it on (the end of the
    previous slab of a run read slab after slab): rows whose samples all lie before it are left out.

    Returns:
        (velocity times [n-1], |velocity| [n-1, k], acceleration times [m], |acceleration| [m, k]); the
        acceleration is the second difference over ``baseline`` samples on each side (NaN rows where a gap
        lies inside the stencil are dropped). Fewer than 2 samples: empty.
    """
    if t.size < 2:
        return t[:0], x[:0], t[:0], x[:0]
    dt, _period = _uniform_steps(t)
    velocity = np.diff(x, axis=0) / dt[:, None]
    keep = np.isfinite(dt) & (np.arange(1, t.size) >= first)  # the velocity between samples i and i + 1
    tv, v = 0.5 * (t[1:] + t[:-1]), np.abs(velocity)
    h = int(baseline)
    if t.size < 2 * h + 1:
        return tv[keep], v[keep], np.empty(0), np.empty((0, x.shape[1]))
    ok = np.isfinite(dt)
    span_ok = np.convolve(ok.astype(int), np.ones(h, int), mode="valid") == h  # h good steps in a row
    left, right = span_ok[:-h], span_ok[h:]
    mid = slice(h, t.size - h)
    ahead = (x[2 * h:] - x[h:-h]) / (t[2 * h:] - t[h:-h])[:, None]
    behind = (x[h:-h] - x[:-2 * h]) / (t[h:-h] - t[:-2 * h])[:, None]
    acc = (ahead - behind) / (0.5 * (t[2 * h:] - t[:-2 * h]))[:, None]
    good = left & right & (np.arange(2 * h, t.size) >= first)  # the stencil's last sample is from ``first`` on
    return tv[keep], v[keep], t[mid][good], np.abs(acc[good])


def drive_motion(t: np.ndarray, x: np.ndarray, first: int = 0) -> tuple[np.ndarray, np.ndarray, int]:
    """The struts' own motion: ``x`` [n, k] averaged twice over DRIVE_AVERAGE consecutive states (centred), at
    the stamps of the middle states; averages over a gap in ``t`` [n] (s) are left out (the gap stays one).
    Returns (stamps [m], averages [m, k], ``first`` for ``rates`` on them: the first average whose stencil reads
    a state from ``first`` on)."""
    width = 2 * (DRIVE_AVERAGE - 1)  # states an average reads beyond its first
    if t.size <= width:
        return t[:0], x[:0], 0
    dt, _period = _uniform_steps(t)
    whole = np.convolve(np.isfinite(dt).astype(int), np.ones(width, int), mode="valid") == width
    y = x
    for _ in range(2):  # each average summed from its own states: a run read in slabs gives the same bits
        y = np.lib.stride_tricks.sliding_window_view(y, DRIVE_AVERAGE, axis=0).mean(axis=-1)
    return (t[DRIVE_AVERAGE - 1:t.size - DRIVE_AVERAGE + 1][whole], y[whole],
            int(whole[:max(first - width, 0)].sum()))


def joint_angles_at(robot: Robot, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Universal (base) and spherical (platform) joint angles [n, 6] (rad) at poses [n, 6]: the angle of
    each leg d_i = p + R a_i - b_i to base z and to the platform's z (R e_z)."""
    rot = rotation_from_rpy(poses[:, 3:])
    d = poses[:, None, :3] + np.einsum("nij,kj->nki", rot, robot.platform_hinges) - robot.base_hinges[None]
    unit = d / np.linalg.norm(d, axis=2, keepdims=True)
    universal = np.arccos(np.clip(unit[..., 2], -1.0, 1.0))
    spherical = np.arccos(np.clip(np.einsum("nki,ni->nk", unit, rot[:, :, 2]), -1.0, 1.0))
    return universal, spherical


def pose_figures(robot: Robot, times: np.ndarray, poses: np.ndarray) -> list[LimitFigure]:
    """The universal and spherical joint angles and the condition number at finite poses [n, 6] (times [n] s),
    computed POSE_SLAB poses at a time (the per-pose matrices of an hour of poses would take gigabytes)."""
    lim = robot.limits
    slabs = []
    for lo in range(0, max(len(times), 1), POSE_SLAB):
        t, p = times[lo:lo + POSE_SLAB], poses[lo:lo + POSE_SLAB]
        universal, spherical = joint_angles_at(robot, p) if len(p) else (np.empty((0, 6)), np.empty((0, 6)))
        cond = np.asarray(condition_number(robot, p)) if len(p) else np.empty(0)
        slabs.append([_worst(np.degrees(universal), t, np.degrees(lim.universal_joint_max), "universal joint angle",
                             "deg", MEASURED_TOLERANCE),
                      _worst(np.degrees(spherical), t, np.degrees(lim.spherical_joint_max), "spherical joint angle",
                             "deg", MEASURED_TOLERANCE),
                      _worst(cond, t, lim.condition_number_max, "condition number", "", MEASURED_TOLERANCE)])
    return [combined_worst(list(parts)) for parts in zip(*slabs, strict=True)]


def combined_worst(parts: list[LimitFigure]) -> LimitFigure:
    """One figure of consecutive slabs' ``_worst`` figures: the first largest worst (a value that is not finite
    the largest, as in ``_worst``), the violations summed."""
    key = [f.worst if np.isfinite(f.worst) else np.inf for f in parts]
    best = parts[int(np.argmax(key))]
    return replace(best, violations=sum(f.violations for f in parts))


def state_figures(robot: Robot, jt: np.ndarray, positions: np.ndarray, first: int = 0) -> list[LimitFigure]:
    """The figures of the joint states (stamps ``jt`` [n] s, positions [n, 12] m: leg_1..6 then vib_1..6), in
    check_limits' order: stroke, strut velocity and acceleration, unit displacement, velocity and acceleration.
    ``first``: the states before it only complete the differences (``rates``) of the ones from it on."""
    lim, unit = robot.limits, robot.vibration_unit
    legs, vib = positions[:, :6], positions[:, 6:12]
    new_t = jt[first:]
    figures = [_stroke(legs[first:] + vib[first:], new_t, lim.stroke_min, lim.stroke_max)]
    tv, v, _ta, _a = rates(jt, legs, 1, first)
    figures.append(_worst(v, tv, lim.strut_velocity_max, "strut velocity", "m/s"))
    drive_t, drive_x, drive_first = drive_motion(jt, legs, first)
    _tv, _v, ta, a = rates(drive_t, drive_x, STRUT_BASELINE, drive_first)
    figures.append(_worst(a, ta, lim.strut_acceleration_max, "strut acceleration", "m/s^2"))
    figures.append(_worst(np.abs(vib[first:]), new_t, unit.amplitude_max, "vibration unit displacement", "m",
                          MEASURED_TOLERANCE))
    tv, v, ta, a = rates(jt, vib, 1, first)
    figures.append(_worst(v, tv, unit.velocity_max, "vibration unit velocity", "m/s"))
    figures.append(_worst(a, ta, unit.acceleration_max, "vibration unit acceleration", "m/s^2"))  # in m/s^2
    return figures


def count_figures(not_finite: int, backwards: int) -> list[LimitFigure]:
    """The counted figures: non-finite values, and steps back in time (/clock and the state stamps)."""
    return [LimitFigure("non-finite values", "", float(not_finite), 0.0, violations=not_finite),
            LimitFigure("time going back (/clock, state stamps)", "steps", float(backwards), 0.0,
                        violations=backwards)]


def not_finite_count(columns: dict, first: int = 0) -> int:
    """Non-finite entries of the "position", "velocity" and "effort" columns [n, k] there are, from row ``first``."""
    return sum(int(np.count_nonzero(~np.isfinite(np.asarray(columns[k], float)[first:])))
               for k in ("position", "velocity", "effort") if k in columns)


def steps_back(times, strict: bool) -> int:
    """Steps of ``times`` [n] that go back (``strict``: also the ones that stay)."""
    steps = np.diff(np.asarray(times, float))
    return int(np.count_nonzero(steps <= 0 if strict else steps < 0))


def check_limits(robot: Robot, joints, pose, clock_times=None) -> list[LimitFigure]:
    """Every limit figure of a recorded run.

    Args:
        robot: the robot (its limits, vibration-unit limits and hinge points).
        joints: (stamps [n] (s), {"position", "velocity", "effort": [n, 12]}) of legs/joint_states, leg_1..6
            then vib_1..6 (``analysis.run_signals.load_signals``).
        pose: (stamps [m] (s), poses [m, 6] (m, rad)) of ground_truth/platform_pose, the true pose.
        clock_times: /clock values [c] (s) in the order they were recorded; None or empty: not checked.

    Returns:
        One LimitFigure per check, in a fixed order (stroke, strut velocity and acceleration, unit
        displacement, velocity and acceleration, joint angles, condition number, finiteness, time).
    """
    jt, cols = joints
    jt = np.asarray(jt, float)
    positions = np.asarray(cols["position"], float).reshape(-1, 12) if len(jt) else np.empty((0, 12))
    figures = state_figures(robot, jt, positions)
    pt, poses = np.asarray(pose[0], float), np.asarray(pose[1], float).reshape(-1, 6)
    finite_pose = np.isfinite(poses).all(axis=1)
    figures += pose_figures(robot, pt[finite_pose], poses[finite_pose])
    not_finite = (not_finite_count(cols) if len(jt) else 0) + int(np.count_nonzero(~finite_pose))
    backwards = steps_back(clock_times, strict=False) if clock_times is not None and len(clock_times) > 1 else 0
    backwards += steps_back(jt, strict=True) if jt.size > 1 else 0
    return figures + count_figures(not_finite, backwards)


def limit_failures(figures: list[LimitFigure]) -> list[str]:
    """One verdict line per violated figure (empty: every limit held)."""
    return [f"limits over the recorded states: {f.line()}" for f in figures if f.violated]
