"""Vibration-unit command buffer of the emulator: vib_* windows on one time base,
limit checks, and a watchdog that ramps the vibration to zero (pure numpy).

The planner streams windows of samples (JointTrajectory with names vib_1..6,
header stamp = the vibration's common start time, time_from_start per
sample). A new window replaces buffered samples from its first time on.
The output ramps to zero with a quintic smoothstep over ``ramp_s`` (no step)
when commands run out (past the last sample), when none arrived for
``watchdog_s``, or on stop()/emergency stop. After such a ramp the buffer
is latched off: it accepts a new window only if it starts from rest.
"""

from __future__ import annotations

import numpy as np

from ..errors import VibrationLimitError
from ..robot import VibrationUnitLimits
from ..vibration.waveform import envelope
from .trajectory import JointTrajectory, _cubic

ACCELERATION_TOLERANCE = 1.05  # sampled windows may overshoot the analytic peak slightly


class VibrationBuffer:
    """Buffered vib_* displacement commands (m) with safety ramp; see module docstring."""

    def __init__(self, limits: VibrationUnitLimits, watchdog_s: float = 0.5, ramp_s: float = 0.05):
        self.limits, self.watchdog_s, self.ramp_s = limits, float(watchdog_s), float(ramp_s)
        self.clear()

    def clear(self) -> None:
        """Forget everything (reset): zero output, not latched."""
        self.times = np.empty(0)
        self.positions = np.empty((0, 6))
        self.velocities = np.empty((0, 6))
        self.last_receive = -np.inf
        self.ramp_start: float | None = None
        self.ramp_reason = ""
        self.latched = False

    @property
    def end(self) -> float:
        return float(self.times[-1]) if self.times.size else -np.inf

    def add(self, traj: JointTrajectory, now: float) -> None:
        """Accept a validated vib_* window (start 0 = now). Raises VibrationLimitError with the leg
        and limit if a sample exceeds the unit's amplitude or acceleration, or if the buffer is
        latched off and the window does not start from rest."""
        start = now if traj.start <= 0 else traj.start
        times = start + traj.times
        pos = traj.positions
        vel = traj.velocities if traj.velocities is not None else np.gradient(pos, times, axis=0) if len(times) > 1 \
            else np.zeros_like(pos)
        self._check_limits(times, pos, vel)
        if self.times.size == 0 or self.latched or self.ramp_start is not None:
            # a (re)start must be at rest where it takes effect (its first sample, or now if that is
            # already past: a late window would otherwise start mid-ramp, i.e. with a step)
            effective = max(now, float(times[0]))
            p_eff = np.array([np.interp(effective, times, pos[:, k]) for k in range(6)])
            v_eff = np.array([np.interp(effective, times, vel[:, k]) for k in range(6)])
            rest_speed = 1e-3 * self.limits.amplitude_max * 2 * np.pi * self.limits.frequency_max
            if np.abs(p_eff).max() > 1e-3 * self.limits.amplitude_max or np.abs(v_eff).max() > rest_speed:
                why = self.ramp_reason or "idle"
                late = f", {now - times[0]:.3f} s after its first sample" if now > times[0] else ""
                raise VibrationLimitError(
                    f"vibration is stopped ({why}); a new command must start from rest (window arrived{late} "
                    f"with {np.abs(p_eff).max() * 1e6:.2f} um / {np.abs(v_eff).max() * 1e3:.3f} mm/s there)",
                    limit_name="restart_from_rest",
                )
            self.latched, self.ramp_start, self.ramp_reason = False, None, ""
            self.times, self.positions, self.velocities = np.empty(0), np.empty((0, 6)), np.empty((0, 6))
        keep = self.times < times[0]
        keep &= self.times >= now - 1.0  # drop history older than a second
        self.times = np.concatenate([self.times[keep], times])
        self.positions = np.vstack([self.positions[keep], pos])
        self.velocities = np.vstack([self.velocities[keep], vel])
        self.last_receive = now

    def _check_limits(self, times, pos, vel) -> None:
        lim = self.limits
        peak = np.abs(pos).max(axis=0)
        if (peak > lim.amplitude_max * (1 + 1e-9)).any():
            leg = int(np.argmax(peak))
            raise VibrationLimitError(
                f"vib_{leg + 1}: displacement {peak[leg] * 1e6:.1f} um exceeds the unit's "
                f"{lim.amplitude_max * 1e6:.1f} um",
                leg=leg + 1, limit_name="amplitude_max", value=float(peak[leg]), limit=lim.amplitude_max,
            )
        if len(times) > 2:
            acc = np.abs(np.diff(vel, axis=0) / np.diff(times)[:, None]).max(axis=0)
            if (acc > lim.acceleration_max * ACCELERATION_TOLERANCE).any():
                leg = int(np.argmax(acc))
                raise VibrationLimitError(
                    f"vib_{leg + 1}: acceleration {acc[leg]:.2f} m/s^2 exceeds the unit's "
                    f"{lim.acceleration_max:.2f} m/s^2",
                    leg=leg + 1, limit_name="acceleration_max", value=float(acc[leg]), limit=lim.acceleration_max,
                )

    def stop(self, now: float, reason: str = "stop") -> None:
        """Start the ramp to zero now (if not already ramping)."""
        if self.ramp_start is None or self.ramp_start > now:
            self.ramp_start, self.ramp_reason = now, reason

    def active(self, now: float) -> bool:
        """True while the output can be non-zero."""
        return self.times.size > 0 and not self.latched and now < self.end + self.ramp_s

    def sample(self, times):
        """(displacement, velocity, acceleration) [n, 6] (m, m/s, m/s^2) at increasing absolute times [n] (s)."""
        times = np.atleast_1d(np.asarray(times, dtype=float))
        pos = np.zeros((times.size, 6))
        vel = np.zeros((times.size, 6))
        acc = np.zeros((times.size, 6))
        if self.times.size == 0 or self.latched:
            return pos, vel, acc
        # watchdog: latch the ramp start once sampling passes it
        if self.ramp_start is None:
            due = min(self.last_receive + self.watchdog_s, self.end)
            if times[-1] >= due:
                self.ramp_start = due
                self.ramp_reason = "commands ran out" if due == self.end else "no commands within the watchdog time"
        bt = self.times
        inside = (times >= bt[0]) & (times <= bt[-1])
        if inside.any() and bt.size > 1:
            t = times[inside]
            seg = np.clip(np.searchsorted(bt, t, side="right") - 1, 0, bt.size - 2)
            h = (bt[seg + 1] - bt[seg])[:, None]
            s = ((t - bt[seg])[:, None]) / h
            p, v, a = _cubic(s, h, self.positions[seg], self.velocities[seg], self.positions[seg + 1],
                             self.velocities[seg + 1])
            pos[inside], vel[inside], acc[inside] = p, v, a
        elif inside.any():
            pos[inside] = self.positions[0]
        after = times > bt[-1]
        if after.any():
            # past the last sample: let the last velocity decay (time constant ramp_s / 5) so the
            # velocity stays continuous; the ramp below takes the (bounded) result to zero
            tau = self.ramp_s / 5.0
            decay = np.exp(-(times[after] - bt[-1]) / tau)[:, None]
            v_end = self.velocities[-1]
            pos[after] = self.positions[-1] + v_end * tau * (1.0 - decay)
            vel[after] = v_end * decay
            acc[after] = -v_end / tau * decay
        if self.ramp_start is not None:
            # output g(t) p(t) with g falling 1 -> 0; envelope of the reversed time gives g, -dg/dt, d2g/dt2
            gain, rate, curve = envelope(self.ramp_start + self.ramp_s - times, None, self.ramp_s)
            g, dg, ddg = gain[:, None], -rate[:, None], curve[:, None]
            acc = acc * g + 2 * vel * dg + pos * ddg
            vel = vel * g + pos * dg
            pos = pos * g
            if times[-1] >= self.ramp_start + self.ramp_s:
                self.latched = True
        return pos, vel, acc
