"""Joint trajectories with ros2_control joint_trajectory_controller semantics (pure numpy).

A trajectory is a start time (s, the header stamp; 0 means "now") plus
points with strictly increasing time_from_start, positions and optional
velocities/accelerations for a fixed set of joint names. Sampling follows
the controller: from the state held when the trajectory starts, a spline to
the first point, then between points a quintic (pos+vel+acc), cubic
(pos+vel) or linear (pos only) segment; before its start the previous
command runs on, after its last point the last point holds.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import cast

import numpy as np

from ..errors import ActuatorLimitError, InvalidInputError
from ..kinematics.limits import check_stroke
from ..splines import cubic_hermite, quintic_hermite, spline_extremes
from .strut_stop import StrutStop, braked, controlled_stop


@dataclass(frozen=True)
class JointTrajectory:
    """Validated trajectory: start (s), times [n] (s from start), positions/velocities/accelerations [n, dof]."""

    start: float
    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray | None
    accelerations: np.ndarray | None

    @property
    def end(self) -> float:
        """Absolute time of the last point (s); meaningful once ``start`` is absolute."""
        return self.start + float(self.times[-1])

    def start_at(self, now: float) -> float:
        """The absolute start (s) of a trajectory received at ``now``: its stamp, or ``now`` for a stamp <= 0
        (joint_trajectory_controller: stamp 0 means "start now"; the one place this rule is written)."""
        return now if self.start <= 0 else self.start


MAX_TRAJECTORY_S = 86400.0  # longest time_from_start taken (s): one day


def build_trajectory(
    joint_names, expected_names, start: float, times, positions, velocities=None, accelerations=None
) -> JointTrajectory:
    """Validate a received trajectory and order its columns as ``expected_names``.

    Args:
        joint_names: the trajectory's joint names, in its column order.
        expected_names: the joint names the columns are ordered to (the same set, any order).
        start: the start (header stamp, s; <= 0 means "now").
        times: time_from_start of each point [n] (s), >= 0 and strictly increasing.
        positions: positions per point, [n, dof] rows (a 2-D array, or n sequences of dof values).
        velocities: velocities per point [n, dof], or None / all rows empty for none.
        accelerations: accelerations per point [n, dof], or None / all rows empty for none; needs
            ``velocities``.

    Returns:
        JointTrajectory with ``start`` (s), ``times`` [n] (s) and positions / velocities / accelerations
        [n, dof] in the column order of ``expected_names`` (velocities / accelerations None if absent).

    Raises:
        InvalidInputError: with the reason: a non-finite start; joint names not exactly
            ``expected_names`` (or repeated); no points; times not finite, negative or not strictly
            increasing; a point with the wrong number of values or without positions; non-finite values;
            velocity / acceleration rows not one per point; accelerations without velocities.
    """
    names = list(joint_names)
    expected = list(expected_names)
    if not np.isfinite(start):
        raise InvalidInputError(f"the start stamp must be finite, got {start}")
    if sorted(names) != sorted(expected) or len(set(names)) != len(names):
        raise InvalidInputError(f"joint names must be exactly {expected} (any order), got {names}")
    order = [names.index(n) for n in expected]
    times = np.asarray(times, dtype=float)
    if times.ndim != 1 or times.size == 0:
        raise InvalidInputError("trajectory has no points")
    if not np.isfinite(times).all() or times[0] < 0 or (np.diff(times) <= 0).any():
        raise InvalidInputError("time_from_start must be finite, >= 0 and strictly increasing")
    if times[-1] > MAX_TRAJECTORY_S:  # a point 1e308 s ahead overflowed the spline into NaN lengths
        raise InvalidInputError(f"time_from_start {times[-1]:g} s exceeds {MAX_TRAJECTORY_S:g} s")

    def table(values, what):
        if values is None:
            return None
        if isinstance(values, np.ndarray) and values.ndim == 2:  # already a table (decoded from CDR)
            if values.shape[1] != len(names):
                raise InvalidInputError(f"every point needs {len(names)} {what}")
            arr = values.astype(float, copy=False)[:, order]
            if not np.isfinite(arr).all():
                raise InvalidInputError(f"non-finite {what}")
            return arr
        rows = [list(v) for v in values]
        if all(len(r) == 0 for r in rows):
            return None
        if any(len(r) != len(names) for r in rows):
            raise InvalidInputError(f"every point needs {len(names)} {what}")
        arr = np.asarray(rows, dtype=float)[:, order]
        if not np.isfinite(arr).all():
            raise InvalidInputError(f"non-finite {what}")
        return arr

    pos = table(positions, "positions")
    if pos is None or pos.shape[0] != times.size:
        raise InvalidInputError("every point needs positions")
    vel, acc = table(velocities, "velocities"), table(accelerations, "accelerations")
    for arr, what in ((vel, "velocities"), (acc, "accelerations")):
        if arr is not None and arr.shape[0] != times.size:
            raise InvalidInputError(f"{arr.shape[0]} rows of {what} for {times.size} points")
    if acc is not None and vel is None:
        raise InvalidInputError("accelerations given without velocities")
    return JointTrajectory(float(start), times, pos, vel, acc)


class TrajectoryFollower:
    """Holds the active trajectory and the state it replaced; samples commanded (p, v, a).

    Interpolation as joint_trajectory_controller's spline: linear with
    positions only, cubic with velocities, quintic with accelerations.
    """

    _active: JointTrajectory | None
    _before: TrajectoryFollower | None
    _brake: StrutStop | None

    def __init__(self, initial_positions):
        self.hold(initial_positions)

    @property
    def active(self) -> JointTrajectory | None:
        """The commanded trajectory (absolute start; it may still wait for its start), or None while holding."""
        return self._active

    @property
    def stop(self) -> StrutStop | None:
        """The controlled stop in force (``brake``), or None."""
        return self._brake

    def hold(self, positions) -> None:
        """Drop any trajectory and hold ``positions`` at rest (the start state)."""
        positions = np.asarray(positions, dtype=float).copy()
        self._active = None
        self._before = None  # the replaced command, sampled before the active trajectory's start
        self._brake = None
        self._from = (positions, np.zeros_like(positions), np.zeros_like(positions))

    def brake(self, at: float, acceleration_max: float) -> StrutStop | None:
        """Bring the command to rest from ``at`` (s) along its own path (``strut_stop.controlled_stop``); a
        command still waiting for its start is dropped first. A stop already in force at ``at`` is kept (it
        is a stop within the limits already). Returns the stop in force, or None when at rest."""
        if self._brake is not None and at < self._brake.end:
            return self._brake
        if self._active is not None and self._active.start > at:  # waiting: what runs now is the replaced command
            before = self._before
            if before is None:
                self.hold(self._from[0])
            else:
                self._active, self._before, self._brake, self._from = (before._active, before._before, before._brake,
                                                                      before._from)
            if self._brake is not None and at < self._brake.end:
                return self._brake
        stop = controlled_stop(self, at, acceleration_max)
        if stop is not None:
            self._brake = stop
        elif not self.finished(at):  # at rest this instant but moving on later: hold here
            self.hold(self.sample([at])[0][0])
        return stop

    def rest_time(self) -> float:
        """From when (s) the command is at rest: the end of the stop or of the trajectory (-inf when holding)."""
        if self._brake is not None:
            return self._brake.end
        return -np.inf if self._active is None else self._active.end

    def replace(self, traj: JointTrajectory, now: float) -> JointTrajectory:
        """Make ``traj`` the running trajectory (start 0 = now); it departs from the
        state commanded at its start time, and until then the replaced command runs on (it
        used to jump to its state at the new start). Returns the trajectory with its absolute start.

        At most the running command and one waiting for its start are kept (what ran before a
        started one is past): a trajectory stamped in the future that replaces one still waiting
        for its start can cut it short (the emulator refuses that case)."""
        start = traj.start_at(now)
        p, v, a = self.sample(np.array([start]))
        before = None
        if self._active is not None:  # a held state needs no record: it is the departure state
            before = copy.copy(self)
            if cast(JointTrajectory, before._active).start <= now:  # a copy of self, whose _active is set
                before._before = None
            elif before._before is not None:
                before._before._before = None
        self._before = before
        self._from = (p[0], v[0], a[0])
        self._brake = None
        self._active = JointTrajectory(start, traj.times, traj.positions, traj.velocities, traj.accelerations)
        return self._active

    def finished(self, now: float) -> bool:
        """True when nothing runs or ``now`` (s) is at or past the end of the active trajectory or stop."""
        return now >= self.rest_time()

    def sample(self, times):
        """Commanded (positions, velocities, accelerations), each [n, dof], at absolute times [n] (s)."""
        times = np.atleast_1d(np.asarray(times, dtype=float))
        stop = self._brake
        if stop is None or not (times >= stop.at).any():
            return self._sample_command(times)
        p, v, a = self._sample_command(times)
        later = times >= stop.at
        p[later], v[later], a[later] = braked(stop, self._sample_command, times[later])
        return p, v, a

    def _sample_command(self, times):
        """The command without its stop: (p, v, a) [n, dof] at absolute times [n] (s)."""
        p0, v0, a0 = self._from
        p = np.tile(p0, (times.size, 1))
        v = np.tile(v0, (times.size, 1))
        a = np.tile(a0, (times.size, 1))
        traj = self._active
        if traj is None:
            return p, v, a
        earlier = times < traj.start
        if self._before is not None and earlier.any():
            p[earlier], v[earlier], a[earlier] = self._before.sample(times[earlier])
        # knots: the departure state at the start, then the points
        kt = np.concatenate([[traj.start], traj.start + traj.times])
        kp = np.vstack([p0, traj.positions])
        kv = None if traj.velocities is None else np.vstack([v0, traj.velocities])
        ka = None if traj.accelerations is None else np.vstack([a0, traj.accelerations])
        after = times >= kt[-1]
        p[after] = kp[-1]
        v[after] = 0.0 if kv is None else kv[-1]
        a[after] = 0.0 if ka is None else ka[-1]
        inside = (times >= kt[0]) & ~after
        if not inside.any():
            return p, v, a
        t = times[inside]
        seg = np.searchsorted(kt, t, side="right") - 1
        seg = np.clip(seg, 0, kt.size - 2)
        h = (kt[seg + 1] - kt[seg])[:, None]
        h = np.where(h > 0, h, 1.0)  # a first point at time 0 makes a zero-length segment
        s = np.clip((t - kt[seg])[:, None] / h, 0.0, 1.0)
        if kv is None:
            p[inside] = kp[seg] + s * (kp[seg + 1] - kp[seg])
            v[inside] = (kp[seg + 1] - kp[seg]) / h
            a[inside] = 0.0
        elif ka is None:
            p[inside], v[inside], a[inside] = cubic_hermite(s, h, kp[seg], kv[seg], kp[seg + 1], kv[seg + 1])
        else:
            p[inside], v[inside], a[inside] = quintic_hermite(
                s, h, kp[seg], kv[seg], ka[seg], kp[seg + 1], kv[seg + 1], ka[seg + 1]
            )
        return p, v, a


SPEED_TOLERANCE = 1.0 + 1e-6
MAX_START_DELAY_S = 10.0
# a velocity step (at a first point at the start time, or at the held end) allowed: this fraction of what the
# acceleration limit changes in one physics step
STEP_SPEED = 1e-3


def checked_command(follower: TrajectoryFollower, traj: JointTrajectory, now: float, limits,
                    max_start_delay_s: float = MAX_START_DELAY_S, step_speed: float = 0.0) -> JointTrajectory:
    """The trajectory that runs (absolute start) when the validated leg command ``traj`` arrives at ``now``
    at ``follower``, after checking it against ``limits`` (robot.limits); raises the reason otherwise.

    joint_trajectory_controller rules (see HardwareEmulator.command_struts): points already past are dropped
    and the motion departs from the state commanded now; positions-only trajectories get finite-difference
    velocities (zero at both ends). The spline from the departure state through every point must stay
    within the stroke, strut_velocity_max and strut_acceleration_max and end at rest.

    Args:
        follower: the follower the command arrives at (its commanded state is the departure state).
        traj: the validated leg command: start (s, 0 = now), times [n] (s), positions [n, 6] (m),
            velocities [n, 6] (m/s) or None, accelerations [n, 6] (m/s^2) or None.
        now: the arrival time (s).
        limits: robot.limits (stroke_min / stroke_max m, strut_velocity_max m/s, strut_acceleration_max m/s^2).
        max_start_delay_s: the latest start accepted, ahead of ``now`` (s).
        step_speed: the velocity step (m/s) allowed at a first point at the start time and at the held end.

    Returns:
        JointTrajectory with the absolute start max(now, start) (s) and only the points after ``now``
        (times relative to that start, velocities filled in).

    Raises:
        ActuatorLimitError: with ``limit_name`` and ``value``: the start is more than ``max_start_delay_s``
            ahead ("max_start_delay_s"); it is in the future while another trajectory still waits for its
            start ("waiting_trajectory"); every point is past ("stale_trajectory"); the trajectory ends
            moving faster than ``step_speed``; a first point at the start time is a position or velocity
            step from the commanded state; the spline's velocity or acceleration exceeds
            strut_velocity_max / strut_acceleration_max (with ``leg`` 1..6).
        StrokeLimitError: the spline's commanded length leaves [stroke_min, stroke_max] (``check_stroke``).
    """
    begin = traj.start_at(now)
    if begin > now + max_start_delay_s:
        raise ActuatorLimitError(
            f"the trajectory starts {begin - now:.3f} s in the future; at most max_start_delay_s "
            f"{max_start_delay_s:g} s (stamp 0 = now)", limit_name="max_start_delay_s",
            value=begin - now, limit=max_start_delay_s)
    waiting = follower.active
    if begin > now and waiting is not None and waiting.start > now:
        raise ActuatorLimitError(
            f"the trajectory starts {begin - now:.3f} s in the future while the previous one still waits for "
            f"its start ({waiting.start - now:.3f} s ahead); stamp it 0 (now) to replace that one",
            limit_name="waiting_trajectory", value=begin - now, limit=0.0)
    pos, vel, acc = traj.positions, traj.velocities, traj.accelerations
    if vel is None:
        vel = np.gradient(pos, traj.times, axis=0) if len(traj.times) > 1 else np.zeros_like(pos)
        vel[[0, -1]] = 0.0
    absolute = begin + traj.times
    future = absolute > now
    if not future.any():
        raise ActuatorLimitError(
            f"every point of the trajectory is in the past (its last point was {now - absolute[-1]:.3f} s ago)",
            limit_name="stale_trajectory", value=float(now - absolute[-1]), limit=0.0)
    departs = max(now, begin)
    running = JointTrajectory(departs, absolute[future] - departs, pos[future], vel[future],
                              None if acc is None else acc[future])
    _check_limits(follower, running, limits, step_speed, late=begin < now and not future.all(), late_by=now - begin)
    return running


def check_departure(follower: TrajectoryFollower, running: JointTrajectory, limits, step_speed: float = 0.0) -> None:
    """The checks of ``checked_command`` for the departure segment alone (the state commanded at the start
    to the first point): what changes when an accepted ``running`` trajectory (absolute start) departs
    from another commanded state than it was checked from. Raises as ``checked_command``."""
    _check_limits(follower, running, limits, step_speed, late=False, late_by=0.0, departure_only=True)


def _check_limits(follower: TrajectoryFollower, traj: JointTrajectory, lim, step_speed: float, late: bool,
                  late_by: float, departure_only: bool = False) -> None:
    """Stroke, velocity and acceleration of the spline the follower will run: from the state
    commanded at the trajectory's start through its points (absolute start, see checked_command);
    ``departure_only``: its first segment only."""
    # traj.velocities: never None here (checked_command fills in missing velocities)
    end_speed = np.abs(cast(np.ndarray, traj.velocities)[-1])
    if end_speed.max() > step_speed and not departure_only:
        leg = int(np.argmax(end_speed))
        raise ActuatorLimitError(f"leg_{leg + 1}: the trajectory ends moving at {end_speed[leg]:.4g} m/s; its last "
                                 f"point is held, so it must end at rest (velocity 0)", leg=leg + 1,
                                 limit_name="strut_acceleration_max", value=float(end_speed[leg]), limit=0.0)
    departure = [x[0] for x in follower.sample([traj.start])]
    knots_t = np.concatenate([[traj.start], traj.start + traj.times])
    knots_p = np.vstack([departure[0], traj.positions])
    knots_v = np.vstack([departure[1], cast(np.ndarray, traj.velocities)])
    knots_a = None if traj.accelerations is None else np.vstack([departure[2], traj.accelerations])
    if knots_t[1] - knots_t[0] < 1e-9:  # a first point at the start time: no departure segment
        knots_t, knots_p, knots_v = knots_t[1:], knots_p[1:], knots_v[1:]
        knots_a = None if knots_a is None else knots_a[1:]
        gap = np.abs(traj.positions[0] - departure[0])
        if gap.max() > 1e-9:
            leg = int(np.argmax(gap))
            raise ActuatorLimitError(f"leg_{leg + 1}: the first point is at the start time but "
                                     f"{gap[leg] * 1e3:.3f} mm away from the commanded length (a step)",
                                     leg=leg + 1, limit_name="strut_velocity_max", value=float(gap[leg]))
        jump = np.abs(cast(np.ndarray, traj.velocities)[0] - departure[1])
        if jump.max() > step_speed:
            leg = int(np.argmax(jump))
            raise ActuatorLimitError(
                f"leg_{leg + 1}: the first point is at the start time but its velocity differs by "
                f"{jump[leg]:.4g} m/s from the commanded velocity (a velocity step)",
                leg=leg + 1, limit_name="strut_acceleration_max", value=float(jump[leg]))
    if departure_only:
        if traj.times[0] < 1e-9:  # no departure segment: the step checks above were all of it
            return
        knots_t, knots_p, knots_v = knots_t[:2], knots_p[:2], knots_v[:2]
        knots_a = None if knots_a is None else knots_a[:2]
    low, high, speed, accel = spline_extremes(
        knots_t, knots_p, knots_v, knots_a, position_bounds=(lim.stroke_min, lim.stroke_max),
        velocity_bound=lim.strut_velocity_max, acceleration_bound=lim.strut_acceleration_max)
    why = f" (it started {late_by:.3f} s ago: the motion departs from the commanded state now)" if late else ""
    check_stroke(low, high, lim, what="commanded length", suffix=why)
    for name, values, limit, unit in (("strut_velocity_max", speed, lim.strut_velocity_max, "m/s"),
                                      ("strut_acceleration_max", accel, lim.strut_acceleration_max, "m/s^2")):
        if (values > limit * SPEED_TOLERANCE).any():
            leg = int(np.argmax(values / limit))
            raise ActuatorLimitError(
                f"leg_{leg + 1}: {name.split('_')[1]} {values[leg]:.4g} {unit} exceeds {name} {limit:.4g} "
                f"{unit}{why}", leg=leg + 1, limit_name=name, value=float(values[leg]), limit=limit)
