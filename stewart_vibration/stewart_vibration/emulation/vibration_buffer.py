"""The one model of the vibration units' command buffer (pure numpy): the emulator follows it and
the leg-force estimator mirrors it, so both agree on what the units were commanded to do.

Commands are vib_* windows (JointTrajectory: header stamp = the vibration's common start t0,
time_from_start per sample, positions m, velocities m/s and optionally accelerations m/s^2).
Between samples the command is a Hermite spline as joint_trajectory_controller interpolates:
quintic where the samples carry accelerations (position, velocity and acceleration continuous:
the vibration planner's windows), cubic otherwise. Protocol:

- A window is checked whole before it is accepted: displacement, velocity and acceleration of
  the spline it produces (``vibration.feasibility.check_command_limits``), and how far ahead it
  reaches (``max_lookahead_s``).
- A window *splices* onto what is buffered at s = max(now, its first sample): the buffered
  command and the new window must agree there in position and velocity (within 0.1 % of the unit's limits);
  from its first sample on the window replaces the buffer (and a stop's ramp: what was faded out by a
  stop never runs again). Between the last buffered sample before the window and its first sample the
  command is the join segment, which starts now from the commanded state if that sample is already past
  (so the output does not jump when the window arrives). When nothing is buffered the command
  is at rest, so a first window must start from rest (a ramp-in). A discontinuous splice is
  refused with the reason; nothing is ever latched: once the output is back at rest, any window
  that starts from rest is accepted.
- Safety ramps (quintic smoothstep to zero over ``ramp_s``, no step; longer where ``ramp_s`` is too short for the
  unit's limits, see ``ramp_duration``): ``stop`` (e-stop, reset)
  starts one at a given time; and when the buffer runs out with the units not at rest (a window
  that does not end in a ramp to zero), they brake to a stop (exponential, starting at the
  acceleration limit) and the watchdog ramps the held offset to zero once no new window has arrived
  for ``watchdog_s`` (at the end of the buffer at the latest if the last window is older than that).
  A window whose end would brake the units beyond their amplitude is refused. Windows of the
  vibration planner always end at rest, so they run out smoothly on their own.

``sample`` is a pure read; ``status`` classifies what the units do at a time (idle, pending,
ramping_in, running, ramping_out) with the active amplitudes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import VibrationLimitError
from ..robot import VibrationUnitLimits
from ..splines import spline_segments
from ..vibration.feasibility import check_command_limits
from ..vibration.waveform import fade_out, product_rule
from .strut_trajectory import JointTrajectory

HISTORY_S = 1.0  # buffered samples kept behind the newest window's first sample
MIN_KNOT_GAP_S = 1e-9  # knots closer than this (a message's stamp resolution) are one knot
RAMP_GROWTH = 1.2  # ratio between the safety-ramp lengths tried
RAMP_MAX_S = 2.0  # the longest safety ramp tried (s)
RAMP_SAMPLE_S = 1e-4  # a tried ramp is sampled this often (s): within 0.07 % of the peak of a 120 Hz sinusoid
RAMP_MIN_SAMPLES = 64
STATUS_SPAN_S = 0.1  # span behind/ahead of "now" over which the status measures the amplitude envelope


@dataclass(frozen=True)
class BufferStatus:
    """What the vibration units do at ``time`` (s).

    state: idle | pending (a window starts later) | ramping_in | running | ramping_out;
    amplitude: (6,) peak |displacement| over the last STATUS_SPAN_S (m); commanded_until: time
    after which the buffered command is at rest (s; -inf if nothing is buffered); ramp_start /
    ramp_reason / ramp_cause: the active or next safety ramp (None / "" if none; the cause one of
    vibration_status.RAMP_CAUSES)."""

    time: float
    state: str
    amplitude: np.ndarray
    commanded_until: float
    ramp_start: float | None
    ramp_reason: str
    ramp_cause: str = ""


def window_arrays(traj: JointTrajectory, now: float):
    """(absolute times [n], positions, velocities, accelerations [n, 6]) of a vib_* trajectory; start
    0 = now. Without velocities the knots get finite-difference velocities (zero for a single point);
    accelerations are NaN rows where the trajectory has none (cubic segments).

    Args:
        traj: the vib_* window (start s, times [n] s from start, positions [n, 6] m, optional velocities
            m/s and accelerations m/s^2).
        now: the receive time (s), the start of a window stamped <= 0.

    Returns:
        (times [n] (s, absolute), positions [n, 6] (m), velocities [n, 6] (m/s),
        accelerations [n, 6] (m/s^2, NaN rows where absent)).
    """
    start = traj.start_at(now)
    times = start + traj.times
    pos = traj.positions
    if traj.velocities is not None:
        vel = traj.velocities
    elif len(times) > 1:
        vel = np.gradient(pos, times, axis=0)
    else:
        vel = np.zeros_like(pos)
    acc = traj.accelerations if traj.accelerations is not None else np.full_like(pos, np.nan)
    return times, pos, vel, acc


class VibrationBuffer:
    """Buffered vib_* displacement commands (m) with safety ramps; see the module docstring."""

    def __init__(self, limits: VibrationUnitLimits, watchdog_s: float = 0.5, ramp_s: float = 0.05,
                 max_lookahead_s: float = 30.0, check_limits: bool = True):
        self.limits, self.watchdog_s, self.ramp_s = limits, float(watchdog_s), float(ramp_s)
        self.max_lookahead_s = float(max_lookahead_s)
        self.check_limits = check_limits  # False: accept any window (a mirror that trusts the checks of another)
        # "at rest": within 0.1 % of the unit's amplitude and of its largest vibration velocity
        self.rest_position = 1e-3 * limits.amplitude_max
        self.rest_velocity = 1e-3 * limits.velocity_max
        self._version = 0  # bumped whenever the buffered command changes (the ramp lengths depend on it)
        self._ramp_cache: tuple[tuple, float] = ((), 0.0)
        self.clear()

    def clear(self) -> None:
        """Forget everything: zero output, no ramp."""
        self.times = np.empty(0)
        self.positions = np.empty((0, 6))
        self.velocities = np.empty((0, 6))
        self.accelerations = np.empty((0, 6))
        self.last_receive = -np.inf
        self.stop_start: float | None = None
        self.stop_reason = ""
        self.stop_cause = ""
        self._version += 1

    # -- commands -----------------------------------------------------------------------
    @property
    def end(self) -> float:
        """Time of the last buffered sample (s); -inf if empty."""
        return float(self.times[-1]) if self.times.size else -np.inf

    def add(self, traj: JointTrajectory, now: float, check_splice: bool = True) -> float:
        """Accept a vib_* window (start 0 = now) received at ``now``; returns the splice time (s).

        ``check_splice`` False (a mirror that starts mid-vibration and trusts another's acceptance): the
        window replaces the whole buffer, unchecked against it (its limits are still checked).
        Raises VibrationLimitError with the reason (limit_name amplitude_max / velocity_max /
        acceleration_max / max_lookahead_s / splice) and changes nothing then.
        """
        times, pos, vel, acc = window_arrays(traj, now)
        if times[-1] > now + self.max_lookahead_s:
            raise VibrationLimitError(
                f"window reaches {times[-1] - now:.3f} s ahead; at most max_lookahead_s {self.max_lookahead_s:g} s",
                limit_name="max_lookahead_s", value=float(times[-1] - now), limit=self.max_lookahead_s)
        if times[-1] < now:
            raise VibrationLimitError(
                f"window ended {now - times[-1]:.3f} s before it arrived (its first sample is "
                f"{now - times[0]:.3f} s old)", limit_name="splice", value=float(now - times[-1]), limit=0.0)
        # a buffered knot closer than MIN_KNOT_GAP_S before the window's first one is replaced by it: a segment that
        # short has no meaningful spline (its h**2 underflows to 0 and the join would be NaN)
        # (history counts back from now too: a window queued further ahead than HISTORY_S must not drop the
        # command the units are following until it starts)
        keep = (self.times < times[0] - MIN_KNOT_GAP_S) & (self.times >= min(now, times[0]) - HISTORY_S) & check_splice
        if self.stop_start is not None:
            keep &= self.times < self.stop_start  # faded out by a stop: never to run again once it is lifted
        kept = [self.times[keep], self.positions[keep], self.velocities[keep], self.accelerations[keep]]
        if check_splice and times[0] > now + MIN_KNOT_GAP_S and self.times.size and \
                not (kept[0].size and kept[0][-1] >= now):
            # the join segment to the window's first sample would start at a past sample and change what the
            # units do now (they brake, ramp out or rest there): it starts now, from the commanded state (a
            # knot just before now gives way to it, as above)
            now_state = self.sample([now])
            far = kept[0] < now - MIN_KNOT_GAP_S
            kept = [np.append(kept[0][far], now)] + [np.vstack([k[far], x]) for k, x in zip(kept[1:], now_state,
                                                                                             strict=True)]
        new_t = np.concatenate([kept[0], times])
        new_p = np.vstack([kept[1], pos])
        new_v = np.vstack([kept[2], vel])
        new_a = np.vstack([kept[3], acc])
        splice = max(now, float(times[0]))
        if check_splice:
            self._check_splice(splice, times, pos, vel, acc, now)
        if self.check_limits:
            # the spline that will be followed, from the last kept sample (the join segment) on -- less the
            # leading samples that repeat buffered ones exactly (checked when they came: a streamed window
            # repeats three quarters of the last) -- and where the units come to a stop if nothing follows
            # (braking at the acceleration limit)
            same = self._repeated_prefix(times, pos, vel, acc) if check_splice else 0
            first = kept[0].size + same - 1 if same else max(kept[0].size - 1, 0)
            check_command_limits(self.limits, new_t[first:], new_p[first:], new_v[first:], new_a[first:])
            settle = np.abs(pos[-1] + vel[-1] * self.braking_time(vel[-1]))
            if (settle > self.limits.amplitude_max).any():
                leg = int(np.argmax(settle))
                raise VibrationLimitError(
                    f"vib_{leg + 1}: the window ends moving at {vel[-1, leg] * 1e3:.3f} mm/s; if nothing follows, "
                    f"the unit would settle at {settle[leg] * 1e6:.1f} um, beyond its amplitude_max "
                    f"{self.limits.amplitude_max * 1e6:.1f} um", leg=leg + 1, limit_name="amplitude_max",
                    value=float(settle[leg]), limit=self.limits.amplitude_max)
        # the window continues what the units do at the splice (ramping out or at rest after a stop), so it
        # replaces the stop ramp: fading it too would fade the continued command twice (a step)
        self.stop_start, self.stop_reason, self.stop_cause = None, "", ""
        self.times, self.positions, self.velocities, self.accelerations = new_t, new_p, new_v, new_a
        self.last_receive = now
        self._version += 1
        return splice

    def _repeated_prefix(self, times, pos, vel, acc) -> int:
        """How many leading knots of a window equal buffered knots (time, position, velocity, acceleration)
        exactly; 0 while a stop ramp is pending (the buffer will change under it)."""
        if self.stop_start is not None or not self.times.size:
            return 0
        i0 = int(np.searchsorted(self.times, times[0]))
        n = min(len(times), len(self.times) - i0)
        if n <= 0:
            return 0
        sl = slice(i0, i0 + n)
        same = (self.times[sl] == times[:n]) & (self.positions[sl] == pos[:n]).all(axis=1) & \
            (self.velocities[sl] == vel[:n]).all(axis=1) & \
            ((self.accelerations[sl] == acc[:n]) | (np.isnan(self.accelerations[sl]) & np.isnan(acc[:n]))).all(axis=1)
        return n if same.all() else int(np.argmin(same))

    def _check_splice(self, splice: float, times, pos, vel, acc, now: float) -> None:
        old_p, old_v, _ = self.sample([splice])
        if splice <= times[0]:
            new_p, new_v = pos[0], vel[0]
        else:
            p, v, _ = spline_segments(times, pos, vel, acc, np.array([splice]))
            new_p, new_v = p[0], v[0]
        jump_p, jump_v = np.abs(new_p - old_p[0]), np.abs(new_v - old_v[0])
        if (jump_p > self.rest_position).any() or (jump_v > self.rest_velocity).any():
            leg = int(np.argmax(np.maximum(jump_p / self.rest_position, jump_v / self.rest_velocity)))
            state = self.status(now).state
            late = f"; it arrived {now - times[0]:.3f} s after its first sample" if now > times[0] else ""
            raise VibrationLimitError(
                f"discontinuous splice at t = {splice:.4f} s (units {state}): vib_{leg + 1} would jump "
                f"{jump_p[leg] * 1e6:.3f} um / {jump_v[leg] * 1e3:.3f} mm/s; a window must continue the buffered "
                f"command, or start from rest when the units are at rest{late}",
                leg=leg + 1, limit_name="splice", value=float(jump_p[leg]), limit=self.rest_position)

    def stop(self, when: float, reason: str, cause: str) -> None:
        """Ramp the output to zero from ``when`` (s) over ``ramp_duration`` (unless a ramp already started earlier)
        for ``reason`` (for people) and ``cause`` (one of vibration_status.RAMP_CAUSES)."""
        if self.stop_start is None or self.stop_start > when:
            self.stop_start, self.stop_reason, self.stop_cause = float(when), reason, cause

    def braking_time(self, velocity) -> np.ndarray:
        """Time constant (s) per unit of the exponential stop from ``velocity`` (m/s) past the last sample:
        |v| / acceleration_max, so it starts at the acceleration limit (at least 0.1 ms)."""
        return np.maximum(np.abs(velocity) / self.limits.acceleration_max, 1e-4)

    # -- read-back ------------------------------------------------------------------------
    def _tail_at_rest(self) -> bool:
        """The last sample is slow (rest_velocity) and where the braking past it settles is within
        rest_position: the braking carries the units v * braking_time further than the sample itself."""
        v_end = self.velocities[-1]
        settled = self.positions[-1] + v_end * self.braking_time(v_end)
        return bool(np.abs(settled).max() <= self.rest_position and np.abs(v_end).max() <= self.rest_velocity)

    def ramp(self) -> tuple[float | None, str]:
        """(start s, reason) of the safety ramp in force: the explicit stop, or the watchdog's ramp when
        the buffer runs out with the units not at rest; (None, "") if none."""
        return self._ramp()[:2]

    def _ramp(self) -> tuple[float | None, str, str]:
        """``ramp`` and its cause ("watchdog" for the watchdog's)."""
        start, reason, cause = self.stop_start, self.stop_reason, self.stop_cause
        if self.times.size and not self._tail_at_rest():
            due = max(self.end, self.last_receive + self.watchdog_s)
            if start is None or due < start:
                start, cause = due, "watchdog"
                reason = (f"watchdog: the commands ran out at {self.end:.3f} s away from rest and no new window "
                          f"arrived within watchdog_s {self.watchdog_s:g} s")
        return start, reason, cause

    def commanded_until(self) -> float:
        """Time (s) from which the command is at rest: the end of the buffer, or of the safety ramp."""
        if not self.times.size:
            return -np.inf
        start, _ = self.ramp()
        if start is None:
            return self.end
        ramp = self.ramp_duration(start)
        return start + ramp if not self._tail_at_rest() else min(self.end, start + ramp)

    def ramp_duration(self, start: float) -> float:
        """Length (s) of a safety ramp starting at ``start`` (s): ``ramp_s``, stretched by RAMP_GROWTH steps
        until the faded output -- g x with g'' x + 2 g' x' + g x'' as its acceleration, x the command -- stays
        within the unit's velocity_max and acceleration_max on samples RAMP_SAMPLE_S apart (a short ramp of a
        strong vibration would exceed them: 0.005 s at 49 Hz / 0.9 g gives 1.4 g); at most RAMP_MAX_S (the
        longest is taken if none fits). Cached per buffered command, start and ramp_s."""
        key = (self._version, float(start), self.ramp_s)
        if self._ramp_cache[0] == key:
            return self._ramp_cache[1]
        lim = self.limits
        count = max(int(np.ceil(np.log(max(RAMP_MAX_S / self.ramp_s, 1.0)) / np.log(RAMP_GROWTH))), 0) + 1
        chosen = max(self.ramp_s, RAMP_MAX_S) if count > 1 else self.ramp_s
        for duration in self.ramp_s * RAMP_GROWTH ** np.arange(count):
            times = np.linspace(start, start + duration, max(RAMP_MIN_SAMPLES, int(np.ceil(duration / RAMP_SAMPLE_S))))
            fade = tuple(x[:, None] for x in fade_out(times, start, duration))
            _, vel, acc = product_rule(self._unfaded(times), fade)
            if np.abs(acc).max() <= lim.acceleration_max * (1 + 1e-6) and np.abs(vel).max() <= lim.velocity_max:
                chosen = float(duration)
                break
        self._ramp_cache = (key, chosen)
        return chosen

    def sample(self, times):
        """(displacement, velocity, acceleration) [n, 6] (m, m/s, m/s^2) at absolute times [n] (s)."""
        times = np.atleast_1d(np.asarray(times, dtype=float))
        pos, vel, acc = self._unfaded(times)
        start, _ = self.ramp()
        if start is not None and self.times.size:
            fade = tuple(x[:, None] for x in fade_out(times, start, self.ramp_duration(start)))
            pos, vel, acc = product_rule((pos, vel, acc), fade)
        return pos, vel, acc

    def _unfaded(self, times):
        """The buffered command without its safety ramp: (p, v, a) [n, 6] at absolute times [n] (s)."""
        pos = np.zeros((times.size, 6))
        vel = np.zeros((times.size, 6))
        acc = np.zeros((times.size, 6))
        bt = self.times
        if bt.size == 0:
            return pos, vel, acc
        inside = (times >= bt[0]) & (times <= bt[-1])
        if inside.any() and bt.size > 1:
            p, v, a = spline_segments(bt, self.positions, self.velocities, self.accelerations, times[inside])
            pos[inside], vel[inside], acc[inside] = p, v, a
        elif inside.any():
            pos[inside] = self.positions[0]
        after = times > bt[-1]
        if after.any():
            # past the last sample the units brake: the velocity decays exponentially, starting at the
            # acceleration limit (continuous position and velocity, stopped within v^2 / a_max)
            v_end = self.velocities[-1]
            tau = self.braking_time(v_end)
            decay = np.exp(-(times[after] - bt[-1])[:, None] / tau)
            pos[after] = self.positions[-1] + v_end * tau * (1.0 - decay)
            vel[after] = v_end * decay
            acc[after] = -v_end / tau * decay
        return pos, vel, acc

    def status(self, now: float) -> BufferStatus:
        """Classify the output around ``now`` (s): see BufferStatus. Amplitudes are peaks of the knots (1 ms
        apart in the planner's windows: within 0.6 % of a 35 Hz sinusoid's peak), scaled by a safety ramp,
        and of the output at the window edges and the buffer's end (the braking tail)."""
        start, reason, cause = self._ramp()
        until = self.commanded_until()
        span = STATUS_SPAN_S
        past = ahead = later = np.zeros(6)
        if self.times.size:
            lo, hi = np.searchsorted(self.times, [now - span, now + span])
            mid = np.searchsorted(self.times, now, side="right")
            values = np.abs(self.positions[lo:hi])
            if start is not None and hi > lo:
                values = values * fade_out(self.times[lo:hi], start, self.ramp_duration(start))[0][:, None]
            edges = np.abs(self.sample([now - span, now, now + span, min(max(self.end, now - span), now + span)])[0])
            tail = edges[3] if self.end < now else np.zeros(6)
            tail_ahead = edges[3] if now <= self.end <= now + span else np.zeros(6)
            past = np.maximum.reduce([values[:mid - lo].max(axis=0) if mid > lo else np.zeros(6), edges[0], edges[1],
                                      tail])
            ahead = np.maximum.reduce([values[mid - lo:].max(axis=0) if hi > mid else np.zeros(6), edges[1],
                                       edges[2], tail_ahead])
            horizon = until if start is None else min(until, start)
            future = slice(mid, np.searchsorted(self.times, horizon))
            if future.stop > future.start:
                later = np.abs(self.positions[future]).max(axis=0)
        rest = self.rest_position
        if past.max() <= rest:
            state = "pending" if max(ahead.max(), later.max()) > rest else "idle"
        elif ahead.max() < 0.97 * past.max():
            state = "ramping_out"
        elif past.max() < 0.97 * max(ahead.max(), later.max()):
            state = "ramping_in"
        else:
            state = "running"
        return BufferStatus(now, state, past, until, start, reason, cause)
