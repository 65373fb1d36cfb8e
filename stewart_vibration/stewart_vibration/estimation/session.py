"""The leg-force estimator's per-run state (pure numpy; the node only converts messages).

``ForceEstimator`` keeps what the emulator follows -- the vib_* window buffer and the leg_*
trajectory, with the emulator's own models (emulation.vibration_buffer, emulation.strut_trajectory) and
its safety ramps as the emulator reports them on vibration/status -- and turns batches of joint
states into modelled leg forces and the external wrench:

    pose = FK(leg_i + vib_i) (warm-started from the previous batch),
    twist = J^-1 L_dot (measured), accel = J^-1 (L_ddot - c),
    F_model = leg_forces(pose, twist, accel), W_ext = -J^T (F_measured - F_model),

with L_ddot the struts' commanded accelerations plus what the legs deliver of the units' demanded ones
(``delivered_units``: fitted from the sensors, so a unit that answers its demand with its own gain and phase is
modelled as it moves). The unit sensors' readings are carried forward by ``unit_sensor_latency_s``
(``sensed_lengths``). Newton-Euler moves each piston with its whole leg (the drawing's emulator lumps the unit
into it); with ``pistons_follow_struts`` (the robot as built: the piston rides its strut and only the unit's
moving mass vibrates) the pistons' share of the units' own acceleration, fitted alone from the unit sensors the
same way, is taken off: F_i -= m_piston x_ddot_unit,i.

A batch gives the same forces as feeding its states one by one (FK converges to 1e-12 m either way; the legs'
response is fitted per fixed window of stamps, whatever the batches).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import cast

import numpy as np

from ..dynamics.newton_euler import leg_forces
from ..emulation.command_size import LEG_TRAJECTORY, check_point_count
from ..emulation.strut_trajectory import STEP_SPEED, JointTrajectory, TrajectoryFollower, checked_command
from ..emulation.vibration_buffer import VibrationBuffer
from ..emulation.vibration_status import STRUT_STOP_CAUSES
from ..errors import InvalidInputError, VibrationLimitError
from ..kinematics import forward_kinematics, jacobian
from ..robot import Robot
from .delivered_units import DeliveredUnits
from .motion import external_wrench, platform_accel, platform_twist
from .sensed_lengths import sensed_leg_lengths

# FK converged to 1e-14 m: a batch (one warm start for all) and single states (each warm-started from the
# previous) then land on the same pose to ~1e-15 m, so their forces agree to ~1e-13 N.
FK_TOLERANCE = 1e-14
# the strut mirror allows the velocity step the emulator allows with its longest physics step (physics_rate_hz >= 200)
MIRROR_STEP_S = 1 / 200


@dataclass(frozen=True)
class ForceEstimate:
    """Per state of a batch: ``ok`` [n] (FK converged; the other rows only where ok), stamps [m] (s),
    pose [m, 6], forces [m, 6] (N, modelled axial), wrench [m, 6] (external wrench on the platform, N and
    N m about the platform origin, base frame; NaN where no effort was measured)."""

    ok: np.ndarray
    stamps: np.ndarray
    pose: np.ndarray
    forces: np.ndarray
    wrench: np.ndarray


class ForceEstimator:
    """Commands in, states in (batches), modelled forces out; see the module docstring."""

    def __init__(self, robot: Robot, vibration_ramp_s: float = 0.05, watchdog_s: float = 0.5,
                 rms_window_s: float = 1.0, unit_sensor_latency_s: float = 0.0, pistons_follow_struts: bool = False):
        self.robot = robot
        self.unit_sensor_latency_s = float(unit_sensor_latency_s)
        self.delivered = DeliveredUnits()
        self.unit_motion = DeliveredUnits() if pistons_follow_struts else None  # the units' own, beside the legs'
        # the emulator's checks too: every window on the topic arrives here, also those the emulator refuses (one
        # 1e4 s ahead made this mirror command metres), so refuse what it refuses
        self.vibration = VibrationBuffer(robot.vibration_unit, watchdog_s, vibration_ramp_s, max_lookahead_s=np.inf)
        self.struts: TrajectoryFollower | None = None  # once a state gives the held lengths
        self.pose = None  # last FK pose (warm start)
        self.errors = RunningForceError(rms_window_s)
        self._last_struts = None  # strut lengths of the newest state
        self.state_time: float | None = None  # stamp of the newest state (the emulator's clock), s
        self._strut_stop: float | None = None  # time of the e-stop whose strut stop is mirrored

    # -- commands (mirrors of the emulator's) ----------------------------------------------
    def command_vibration(self, traj: JointTrajectory, now: float | None = None) -> bool:
        """Buffer a vib_* window as the emulator does (raises the emulator's refusal reasons). ``now``
        (s) defaults to the emulator's time as the newest joint state gives it (before any state: the
        window's own start, i.e. on time).

        A fresh mirror (no window taken since this estimator started) cannot splice a window that starts
        mid-vibration -- it joined (was restarted) during one: it takes that window as its new history,
        trusting the emulator's acceptance (the limits are still checked), and returns True; otherwise
        False. From then on windows splice as usual."""
        if now is None:
            now = self.state_time if self.state_time is not None else traj.start_at(0.0)
        try:
            self.vibration.add(traj, now)
            return False
        except VibrationLimitError as exc:
            if exc.limit_name != "splice" or np.isfinite(self.vibration.last_receive):
                raise
        self.vibration.add(traj, now, check_splice=False)
        return True

    def command_struts(self, traj: JointTrajectory, now: float | None = None) -> None:
        """Follow a leg_* trajectory from the newest measured lengths (raises if none was measured yet);
        ``now`` (s) defaults to the newest state's stamp. Checked per strut and for its size as the emulator
        checks it (every command on the topic arrives here, also those the emulator refuses), raising its
        reasons. Not for what the six struts do together (``strut_acceptance``): that check costs 25-100 ms,
        which would stall the 500 Hz estimates on every move (the force guard trips on estimates older than
        0.25 s); a command the emulator refuses only for that (adversarial, never the kinematics node's) is
        mirrored as at most strut_acceleration_max of modelled strut acceleration until its end."""
        now = self.state_time if now is None else now
        if self.struts is None:
            if self._last_struts is None:
                raise InvalidInputError("no legs/joint_states yet (start state unknown)")
            self.struts = TrajectoryFollower(self._last_struts)
        lim = self.robot.limits
        check_point_count(len(traj.times), LEG_TRAJECTORY)
        # now: a float here (struts exist only after a state, which set state_time)
        running = checked_command(self.struts, traj, cast(float, now), lim,
                                  step_speed=STEP_SPEED * lim.strut_acceleration_max * MIRROR_STEP_S)
        self.struts.replace(running, cast(float, now))

    def apply_ramp(self, start: float | None, reason: str, cause: str) -> None:
        """A safety ramp the emulator reports (e-stop, deactivate, shutdown, watchdog) from ``start`` (s), its
        ``reason`` and ``cause`` (emulation.vibration_status.RAMP_CAUSES); ignored when it predates the newest window
        (a stale report about an earlier vibration). For the strut stops (STRUT_STOP_CAUSES) the struts brake as
        the emulator's do (``TrajectoryFollower.brake``)."""
        if start is not None and start >= self.vibration.last_receive:
            self.vibration.stop(start, reason, cause)
        if start is not None and cause in STRUT_STOP_CAUSES and self.struts is not None and start != self._strut_stop:
            self._strut_stop = start  # the emulator's controlled stop of the struts, as it commands it
            self.struts.brake(start, self.robot.limits.strut_acceleration_max)

    # -- states ----------------------------------------------------------------------------
    def estimate(self, stamps, struts, vib, strut_rates, vib_rates, efforts=None) -> ForceEstimate:
        """Modelled forces for states [n]: stamps (s), strut and vibration positions / rates [n, 6]
        (m, m/s), measured axial forces [n, 6] (N; None or NaN rows = not measured)."""
        stamps = np.asarray(stamps, float)
        struts, vib, vib_rates = np.asarray(struts, float), np.asarray(vib, float), np.asarray(vib_rates, float)
        units = sensed_leg_lengths(np.zeros_like(vib), vib, vib_rates, self.unit_sensor_latency_s)
        lengths = struts + units
        rates = np.asarray(strut_rates, float) + vib_rates
        self._last_struts = struts[-1]
        self.state_time = float(stamps[-1])
        if self.struts is None:
            self.struts = TrajectoryFollower(struts[-1])
        elif self.struts.finished(stamps[-1]):
            self.struts.hold(struts[-1])  # at rest at the measured lengths
        guess = self.robot.home_pose if self.pose is None else self.pose
        fk = forward_kinematics(self.robot, lengths, guess=np.broadcast_to(guess, lengths.shape), tol=FK_TOLERANCE,
                                check_limits=False)
        ok = fk.converged & fk.assembly_ok
        if not ok.any():
            self.pose = None
            return ForceEstimate(ok, *(np.empty((0, 6)) for _ in range(4)))
        pose = fk.pose[ok]
        times = stamps[ok]
        jac = jacobian(self.robot, pose)
        twist = platform_twist(self.robot, pose, rates[ok], jac)
        demand = self.vibration.sample(times)
        accel_legs = self.struts.sample(times)[2] + self.delivered.add(times, lengths[ok], demand)
        accel = platform_accel(self.robot, pose, twist, accel_legs, jac)
        forces = leg_forces(self.robot, pose, twist, accel)
        if self.unit_motion is not None:  # the pistons do not vibrate with the units' sliders
            forces -= self.robot.leg.piston_mass * self.unit_motion.add(times, units[ok], demand)
        self.pose = pose[-1]
        wrench = np.full_like(forces, np.nan)
        if efforts is not None:
            measured = np.asarray(efforts, float)[ok] - self.robot.load_cell_offsets  # the cells' zeros
            have = np.isfinite(measured).all(axis=1)
            if have.any():
                wrench[have] = external_wrench(self.robot, pose[have], measured[have], forces[have], jac[have])
                self.errors.add_batch(times[have], measured[have], forces[have])
        return ForceEstimate(ok, times, pose, forces, wrench)


class RunningForceError:
    """RMS of F_measured - F_model over the last ``window_s`` seconds, and the force amplitude.

    amplitude: per leg half the peak-to-peak of the measured force in the window
    (the vibration's force amplitude); relative error = RMS error / RMS over the
    legs of those amplitudes. Samples are kept in batches (arrays), trimmed by time.
    """

    def __init__(self, window_s: float = 1.0):
        self.window_s = float(window_s)
        self._batches: deque = deque()  # (stamps [n], measured [n, 6], model [n, 6])

    def add(self, stamp: float, measured, model) -> None:
        """One sample: stamp (s), measured and modelled forces (6,) (N)."""
        self.add_batch([stamp], np.reshape(measured, (1, -1)), np.reshape(model, (1, -1)))

    def add_batch(self, stamps, measured, model) -> None:
        """Samples [n]: stamps (s), measured and modelled forces [n, 6] (N)."""
        stamps = np.asarray(stamps, float)
        if not stamps.size:
            return
        if self._batches and self._batches[-1][0][-1] > stamps[0]:  # time went backwards (sim reset): restart
            self._batches.clear()
        self._batches.append((stamps, np.asarray(measured, float), np.asarray(model, float)))
        cutoff = stamps[-1] - self.window_s
        while self._batches and self._batches[0][0][-1] < cutoff:
            self._batches.popleft()
        first = self._batches[0]
        if first[0][0] < cutoff:
            keep = first[0] >= cutoff
            self._batches[0] = (first[0][keep], first[1][keep], first[2][keep])

    def __len__(self) -> int:
        return sum(len(b[0]) for b in self._batches)

    def summary(self) -> dict:
        """rms_error_n (6,), rms_error_all_n, force_amplitude_n (6,), relative_error, samples."""
        if not len(self):
            return {"samples": 0}
        measured = np.concatenate([b[1] for b in self._batches])
        model = np.concatenate([b[2] for b in self._batches])
        err = measured - model
        rms = np.sqrt((err**2).mean(axis=0))
        amp = (measured.max(axis=0) - measured.min(axis=0)) / 2.0
        rms_all = float(np.sqrt((err**2).mean()))
        amp_all = float(np.sqrt((amp**2).mean()))
        return {
            "samples": len(measured),
            "rms_error_n": rms,
            "rms_error_all_n": rms_all,
            "force_amplitude_n": amp,
            "relative_error": rms_all / amp_all if amp_all > 0 else float("inf"),
        }
