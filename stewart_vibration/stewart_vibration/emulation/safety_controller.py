"""The emulated robot's own safety layer (pure numpy, no physics): what it accepts and how it stops, as a
real drive's safety controller does, whoever sent the command.

``SafetyController`` holds the commanded motion -- the strut trajectory follower, the vibration command
buffer, the vibration status, the e-stop latch and a latched physics fault -- and changes it only through:

- ``command_struts``: a leg_* trajectory, accepted only after every check of ``strut_acceptance`` (per strut,
  the six together in the workspace, the stop reserve) on what will actually run; at most
  MAX_TRAJECTORY_POINTS points (``command_size``);
- ``command_vibration``: a vib_* window (``VibrationBuffer.add``: the unit's limits, continuity);
- ``emergency_stop`` (latched), ``halt`` (deactivate, shutdown: not latched): the vibration ramps to zero
  within the unit's limits (``VibrationBuffer.ramp_duration``) and the struts brake to rest along their
  commanded path within strut_acceleration_max (``strut_stop``), so every stop ends inside the stroke and
  the workspace the command was accepted in;
- ``reset``: out of the e-stop, home along a checked move that departs where the stop comes to rest;
- ``latch_physics_fault``: the physics diverged (``physics_guard``); everything is refused from then on.

Time is passed in (s, the emulator's sim time); ``HardwareEmulator`` adds the physics. Without physics the
controller's commanded references are what the servos follow: the property tests drive it directly.
"""

from __future__ import annotations

import copy
from contextlib import nullcontext
from dataclasses import dataclass

import numpy as np

from ..errors import ActuatorLimitError, EmergencyStopLatchedError, PhysicsFaultError
from ..kinematics import inverse_kinematics
from ..motion.profiles import minimum_jerk, minimum_jerk_duration
from ..robot import LEG_NAMES, VIB_NAMES, Robot
from .command_size import LEG_TRAJECTORY, VIBRATION_WINDOW, check_point_count
from .physics_guard import PhysicsFault
from .strut_acceptance import accept_strut_command, check_together
from .strut_trajectory import (
    MAX_START_DELAY_S,
    STEP_SPEED,
    JointTrajectory,
    TrajectoryFollower,
    build_trajectory,
    check_departure,
)
from .vibration_buffer import VibrationBuffer
from .vibration_status import CAUSE_OF, EMERGENCY_STOP, PHYSICS_FAULT, VibrationReport, VibrationStatusTracker

RESET_SPEED = 0.5  # fraction of strut_velocity_max of the move home after an e-stop
RESET_MIN_S = 0.5  # shortest move home (s)
RESET_POINTS = 50
SYNC_POINTS = 200  # a command this short (points and s) arriving while the struts move is checked under the lock
SYNC_S = 10.0


@dataclass(frozen=True)
class StrutSnapshot:
    """What a strut command is checked against outside a lock: the command version, the time (s), a copy of the
    strut follower and the platform pose then (m, rad; None: home as the FK's warm start)."""

    version: int
    now: float
    follower: TrajectoryFollower
    pose: np.ndarray | None


class SafetyController:
    """The commanded motion of the robot and every rule that changes it (see the module docstring).

    Args:
        robot: the robot (limits, geometry, vibration unit).
        step_s: the physics step (s): the velocity step a strut command may make is STEP_SPEED of what the
            acceleration limit changes in one step.
        watchdog_s, vibration_ramp_s, max_lookahead_s: the vibration buffer's (``VibrationBuffer``).
        max_start_delay_s: the latest start of a strut command ahead of now (s).
    """

    def __init__(self, robot: Robot, step_s: float, watchdog_s: float = 0.5, vibration_ramp_s: float = 0.05,
                 max_lookahead_s: float = 30.0, max_start_delay_s: float = MAX_START_DELAY_S):
        self.robot = robot
        self.step_speed = STEP_SPEED * robot.limits.strut_acceleration_max * float(step_s)
        self.max_start_delay_s = float(max_start_delay_s)
        self.home_lengths = inverse_kinematics(robot, robot.home_pose)
        self.struts = TrajectoryFollower(self.home_lengths)
        self.vibration = VibrationBuffer(robot.vibration_unit, watchdog_s, vibration_ramp_s, max_lookahead_s)
        self.status = VibrationStatusTracker()
        self.estopped = False
        self.fault: PhysicsFault | None = None
        self.version = 0  # bumped by every change of the commanded motion

    def changed(self) -> None:
        """The commanded motion changed (cached references are stale)."""
        self.version += 1

    # -- strut commands ---------------------------------------------------------------------------
    def command_struts(self, now: float, names, start, times, positions, velocities=None, accelerations=None, *,
                       pose=None, clock=None, lock=None) -> JointTrajectory:
        """Validate and run a leg_* trajectory arriving at ``now`` (s); returns it as it runs (absolute start).

        With another thread stepping time (the emulator's physics), pass ``clock`` (() -> the time now, s),
        ``lock`` (shared with that thread) and ``pose`` as a callable (() -> the platform pose now): the checks
        run outside the lock on a snapshot, only the commit takes it (``commit_struts``) -- except for a short
        command (at most SYNC_POINTS points over SYNC_S) arriving while the struts move: a replan or the force
        guard's stop, whose timing matters (it is planned for the state at its arrival) and whose check is
        cheap (~15 ms), is checked and committed at once under the lock, with physics waiting.

        Raises the typed error of the first violation (``strut_acceptance``), ActuatorLimitError
        "emergency_stop" while the e-stop is latched, PhysicsFaultError after a physics fault; nothing changes then.
        """
        guard = nullcontext() if lock is None else lock
        clock = clock if clock is not None else (lambda: now)
        pose_now = pose if callable(pose) else (lambda: pose)
        check_point_count(len(times), LEG_TRAJECTORY)
        traj = build_trajectory(names, LEG_NAMES, start, times, positions, velocities, accelerations)
        with guard:
            self.refuse_when_stopped()
            arrival = clock()
            if not self.struts.finished(arrival) and len(traj.times) <= SYNC_POINTS and traj.times[-1] <= SYNC_S:
                running = self.accept_struts(traj, StrutSnapshot(self.version, arrival, self.struts, pose_now()))
                self.changed()
                return self.struts.replace(running, arrival)
            snapshot = StrutSnapshot(self.version, arrival, copy.copy(self.struts), pose_now())
        running = self.accept_struts(traj, snapshot)
        with guard:
            return self.commit_struts(traj, running, snapshot, clock(), pose_now())

    def accept_struts(self, traj: JointTrajectory, snapshot: StrutSnapshot) -> JointTrajectory:
        """Every check of ``traj`` against ``snapshot`` (no lock needed: it reads the snapshot only)."""
        return accept_strut_command(self.robot, snapshot.follower, traj, snapshot.now, start_pose=snapshot.pose,
                                    max_start_delay_s=self.max_start_delay_s, step_speed=self.step_speed)

    def commit_struts(self, traj: JointTrajectory, running: JointTrajectory, snapshot: StrutSnapshot, now: float,
                      pose=None) -> JointTrajectory:
        """Run ``running`` (checked at ``snapshot``) from ``now`` (s, under the lock): unchanged if it departs
        from the same commanded state as checked; shifted to start now if stamped "now" and departing from a
        state at rest since; with its departure segment checked again if stamped "now" and departing from a
        moving state; checked whole again if another command came in between or its stamp lies in the past."""
        self.refuse_when_stopped()
        same = self.version == snapshot.version
        if not (same and (now == snapshot.now or running.start > now)):
            if same and traj.start <= 0:  # stamped "now": it departs now, later than checked
                shifted = JointTrajectory(now, running.times, running.positions, running.velocities,
                                          running.accelerations)
                if not snapshot.follower.finished(snapshot.now):  # moving: a new departure segment
                    check_departure(self.struts, shifted, self.robot.limits, self.step_speed)
                    check_together(self.robot, self.struts, shifted, now, now + float(shifted.times[0]),
                                   start_pose=pose)
                running = shifted
            else:
                running = self.accept_struts(traj, StrutSnapshot(self.version, now, self.struts, pose))
        self.changed()
        return self.struts.replace(running, now)

    def refuse_when_stopped(self) -> None:
        """Raise the refusal of every motion command while a physics fault or the e-stop is latched."""
        if self.fault is not None:
            raise PhysicsFaultError(f"physics fault latched at {self.fault.time:.3f} s: {self.fault.reason}; the "
                                    "robot is held (reconfigure the emulator)", time=self.fault.time,
                                    reason=self.fault.reason)
        if self.estopped:
            raise EmergencyStopLatchedError("emergency stop is active: call reset first", limit_name="emergency_stop")

    # -- vibration commands -----------------------------------------------------------------------
    def command_vibration(self, now: float, names, start, times, positions, velocities=None,
                          accelerations=None) -> float:
        """Validate and splice a vib_* window arriving at ``now`` (s); returns the splice time (s). Raises
        InvalidInputError / VibrationLimitError / EmergencyStopLatchedError / PhysicsFaultError with the
        reason; the refusal is also recorded in the vibration status. At most MAX_WINDOW_POINTS points."""
        try:
            self.refuse_when_stopped()
            check_point_count(len(times), VIBRATION_WINDOW)
            traj = build_trajectory(names, VIB_NAMES, start, times, positions, velocities, accelerations)
            splice = self.vibration.add(traj, now)
        except Exception as exc:
            self.status.refused(now, float(start) if np.isfinite(start) else 0.0,
                                getattr(exc, "outcome", "INTERNAL_ERROR"), str(exc))
            raise
        self.status.accepted(now, float(start))
        self.changed()
        return splice

    # -- stops ------------------------------------------------------------------------------------
    def emergency_stop(self, now: float) -> None:
        """``halt`` at ``now`` (s), latched until ``reset``."""
        self.halt(now, EMERGENCY_STOP)
        self.estopped = True

    def halt(self, now: float, reason: str) -> None:
        """A safety stop at ``now`` (s) that does not latch (lifecycle deactivate, shutdown): the vibration ramps
        to zero within the unit's limits and the struts brake to rest along their commanded path within
        strut_acceleration_max (``TrajectoryFollower.brake``); a stop already under way goes on. ``reason``
        (a key of CAUSE_OF) names it in the vibration status, with its cause (the estimator mirrors the strut stop
        for STRUT_STOP_CAUSES)."""
        self.vibration.stop(now, reason, CAUSE_OF[reason])
        if not self.estopped:
            self.struts.brake(now, self.robot.limits.strut_acceleration_max)
            self.status.safety_ramp(now, reason, CAUSE_OF[reason])
        self.changed()

    def stop_vibration(self, now: float, reason: str) -> None:
        """Ramp the vibration to zero from ``now`` (s) within the unit's limits for ``reason`` (a unit's own
        protection, e.g. its travel): the struts keep their commands; nothing latches. Ignored while the e-stop
        is latched (its ramp is already under way)."""
        if self.estopped:
            return
        self.vibration.stop(now, reason, "unit_protection")
        self.status.safety_ramp(now, reason, "unit_protection")
        self.changed()

    def at_rest(self, now: float) -> bool:
        """True when the commanded struts and vibration units are at rest from ``now`` (s) on."""
        return self.struts.finished(now) and self.vibration.commanded_until() <= now

    def reset(self, now: float, pose=None) -> float:
        """Clear a latched e-stop and move home; returns the time until home (s).

        The move plans from the commanded state: while the e-stop's stop still brakes, it starts where that
        stop comes to rest, when it does; then a minimum-jerk move home at RESET_SPEED of the strut speed,
        accepted like any strut command (``pose``: the platform pose now, the FK's warm start).

        Raises ActuatorLimitError (limit_name "reset") when no e-stop is latched: reset moves the robot, so it
        only acts as the way out of an e-stop; PhysicsFaultError after a physics fault; the acceptance's errors
        if the way home is refused (the e-stop stays latched then)."""
        if self.fault is not None:
            self.refuse_when_stopped()
        if not self.estopped:
            raise ActuatorLimitError("no emergency stop is latched: reset only clears an e-stop (it moves the "
                                     "robot home)", limit_name="reset")
        depart = max(now, self.struts.rest_time())
        current = self.struts.sample([depart])[0][0]
        duration = minimum_jerk_duration(current, self.home_lengths,
                                         RESET_SPEED * self.robot.limits.strut_velocity_max, RESET_MIN_S)
        times = np.linspace(duration / RESET_POINTS, duration, RESET_POINTS)
        pos, vel, acc = minimum_jerk(current, self.home_lengths, duration, times)
        home = build_trajectory(LEG_NAMES, LEG_NAMES, depart if depart > now else 0.0, times, pos, vel, acc)
        running = accept_strut_command(self.robot, self.struts, home, now, start_pose=pose,
                                       max_start_delay_s=max(self.max_start_delay_s, depart - now),
                                       step_speed=self.step_speed)
        self.estopped = False
        self.struts.replace(running, now)
        self.changed()
        return depart - now + duration

    def latch_physics_fault(self, now: float, reason: str, held_lengths) -> None:
        """The physics diverged at ``now`` (s): latch the fault (and the e-stop), hold ``held_lengths`` (6,) (m),
        drop the vibration; every command is refused from then on."""
        if self.fault is not None:
            return
        self.fault = PhysicsFault(now, reason)
        self.vibration.stop(now, PHYSICS_FAULT, CAUSE_OF[PHYSICS_FAULT])
        self.struts.hold(held_lengths)
        self.status.safety_ramp(now, PHYSICS_FAULT, CAUSE_OF[PHYSICS_FAULT])
        self.estopped = True
        self.changed()

    def place_at_rest(self, lengths) -> None:
        """Hold ``lengths`` (6,) (m) at rest with nothing buffered and no e-stop (a fresh start state)."""
        if self.fault is not None:
            self.refuse_when_stopped()
        self.struts.hold(lengths)
        self.vibration.clear()
        self.estopped = False
        self.changed()

    def vibration_report(self, now: float) -> tuple[VibrationReport, bool]:
        """(report, state changed) of what the vibration units do at ``now`` (s) (``vibration_status``)."""
        fault = None if self.fault is None else self.fault.reason
        return self.status.update(self.vibration.status(now), self.estopped, now, fault=fault)
