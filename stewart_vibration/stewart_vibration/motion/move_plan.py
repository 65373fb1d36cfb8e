"""A move to a target pose (pure): whether the kinematics node takes it now, how fast it may go, and its
checked minimum-jerk leg trajectory.

A target is taken when it is reachable, the node knows where the robot is, the force guard does not block
that direction and no move is under way or came too soon (motion.target_gate). The move runs at the goal's
share of strut_velocity_max, slower while the wrench estimates lag (ForceGuard.speed_limit). Its trajectory
is the shortest minimum-jerk move of the struts within that speed (motion.profiles), sampled every
``sample_period`` (long moves more sparsely: the robot takes at most ``max_points``), and checked along the
whole move for what the six struts do together (kinematics.workspace.check_strut_path, the robot's own
check) and, under a tissue model, for the strut forces at every sample (motion.paths.check_path_forces).

Lengths in m, speeds in m/s, times in s (from the move's start; ``sim_now`` the robot's clock, ``wall_now``
monotonic), poses (6,) [x, y, z, roll, pitch, yaw] in m and rad in the base frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..dynamics.tissue import TissueModel
from ..errors import RefusedError
from ..kinematics import check_pose, forward_kinematics
from ..kinematics.workspace import check_strut_path
from ..robot import Robot
from .force_guard import ForceGuard
from .paths import check_path_forces, interpolate_poses
from .profiles import minimum_jerk, minimum_jerk_duration
from .target_gate import TargetGate


@dataclass(frozen=True)
class MoveSpeed:
    """A move's strut speed (m/s): what the goal's speed scale gives and what the force guard allows."""

    asked: float
    allowed: float

    @property
    def slowed(self) -> bool:
        """Whether the guard holds the move below what the goal asked (its estimates lag)."""
        return self.allowed < self.asked

    @property
    def value(self) -> float:
        """The speed the move runs at (m/s)."""
        return self.allowed if self.slowed else self.asked


@dataclass(frozen=True)
class LegTrajectory:
    """A move's strut trajectory at its sample times [n] (s from the start; the last is the move's end):
    positions [n, 6] (m), velocities [n, 6] (m/s) and accelerations [n, 6] (m/s^2)."""

    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray

    @property
    def duration(self) -> float:
        """The move's duration (s)."""
        return float(self.times[-1])


class MovePlanner:
    """The moves of one robot: ``admit`` a target, its ``speed``, then its ``trajectory``. ``max_points``: the
    most points the robot takes in one leg trajectory; ``tissue``: the load whose strut forces are checked."""

    def __init__(self, robot: Robot, guard: ForceGuard, gate: TargetGate, max_points: int,
                 tissue: TissueModel | None = None):
        self.robot, self.guard, self.gate = robot, guard, gate
        self.max_points, self.tissue = int(max_points), tissue

    def admit(self, target, lengths, pose, sim_now: float, wall_now: float) -> np.ndarray:
        """The strut lengths (6,) at ``target`` if a move there from ``pose`` (the newest estimate; None before
        any state, like the measured ``lengths``) is taken now, which uses one of the rate's tokens. Raises the
        pose's refusal, RefusedError NOT_READY (nothing measured yet), the guard's GUARD_BLOCKED or RefusedError
        BUSY (a move under way, or too many targets), in that order."""
        goal_lengths = check_pose(self.robot, target)
        if lengths is None or pose is None:
            raise RefusedError("NOT_READY", "no legs/joint_states received yet")
        self.guard.check_target(pose, target)
        refusal = self.gate.refusal(sim_now, wall_now)
        if refusal is not None:
            raise RefusedError("BUSY", refusal)
        return goal_lengths

    def speed(self, speed_scale: float) -> MoveSpeed:
        """The strut speed of a move at ``speed_scale`` (fraction of strut_velocity_max) under the guard now."""
        return MoveSpeed(self.robot.limits.strut_velocity_max * speed_scale, self.guard.speed_limit())

    def trajectory(self, start_lengths, start_pose, goal_lengths, goal_pose, speed: float, min_duration: float,
                   sample_period: float) -> LegTrajectory:
        """The checked minimum-jerk trajectory from ``start_lengths`` (where the robot is, at ``start_pose``) to
        ``goal_lengths`` (at ``goal_pose``): at most ``speed``, at least ``min_duration`` long, a sample every
        ``sample_period`` up to ``max_points``. Raises the first violation along the move (the workspace's, or a
        TissueLimitError naming waypoint k = sample k, 0 being the start)."""
        duration = minimum_jerk_duration(start_lengths, goal_lengths, speed, min_duration)
        count = min(max(int(np.ceil(duration / sample_period)), 2), self.max_points)
        times = np.linspace(duration / count, duration, count)
        positions, velocities, accelerations = minimum_jerk(start_lengths, goal_lengths, duration, times)
        check_strut_path(self.robot, lambda t: minimum_jerk(start_lengths, goal_lengths, duration, t)[0], 0.0,
                         duration, knots=times, start_pose=start_pose, what="the move")
        if self.tissue is not None:
            guesses = interpolate_poses(start_pose, goal_pose, count + 1)[1:]
            fk = forward_kinematics(self.robot, positions, guess=guesses)
            fk.raise_for_failure()
            check_path_forces(self.robot, fk.pose, self.tissue, first_index=1, count=count + 1)
        return LegTrajectory(times, positions, velocities, accelerations)
