"""The robot's own safety layer for strut commands (pure numpy), as a drive's safety controller checks them:
what the emulator accepts -- and the estimator, which mirrors it, accepts with it.

A leg_* trajectory is accepted only if the motion the follower will actually run, from the state commanded
when it departs through every point:

1. keeps every strut within its stroke, velocity and acceleration limits and ends at rest
   (``strut_trajectory.checked_command``);
2. keeps the six together inside the workspace at every instant: platform hinges above the base, joint
   angles, condition number, FK converged (``kinematics.workspace.check_strut_path``, on a grid fine enough
   that nothing slips between its samples);
3. leaves room to stop: from every instant a controlled stop within strut_acceleration_max exists
   (``strut_stop.check_stop_reserve``; in its last STOP_RESERVE_S the command is its own stop) -- and that
   stop follows the checked path, so it ends inside the stroke and the workspace too.

Otherwise it is refused with the typed error of the first violation (its ``limit_name``, ``leg``, ``time``).
"""

from __future__ import annotations

import copy

from ..kinematics.workspace import check_strut_path
from ..robot import Robot
from .strut_stop import check_stop_reserve
from .strut_trajectory import MAX_START_DELAY_S, JointTrajectory, TrajectoryFollower, checked_command


def accept_strut_command(robot: Robot, follower: TrajectoryFollower, traj: JointTrajectory, now: float, *,
                         start_pose=None, max_start_delay_s: float = MAX_START_DELAY_S,
                         step_speed: float = 0.0) -> JointTrajectory:
    """The trajectory that runs (absolute start) when ``traj`` arrives at ``follower`` at ``now`` (s), after
    every check of the module docstring; raises the first violation's typed error otherwise. Nothing changes.

    Args:
        robot: the robot (its limits and geometry).
        follower: the follower the command arrives at.
        traj: the validated leg command (``build_trajectory``).
        now: the arrival time (s).
        start_pose: the platform pose now (m, rad), the FK's warm start (default home).
        max_start_delay_s, step_speed: as ``checked_command``.

    Raises:
        ActuatorLimitError, StrokeLimitError: per strut (``checked_command``) and "stop_reserve".
        UnreachablePoseError, JointLimitError, SingularPoseError: the workspace (``check_strut_path``).
    """
    running = checked_command(follower, traj, now, robot.limits, max_start_delay_s, step_speed)
    check_together(robot, follower, running, now, running.end, start_pose=start_pose)
    return running


def check_together(robot: Robot, follower: TrajectoryFollower, running: JointTrajectory, start: float, end: float,
                   *, start_pose=None, what: str = "the trajectory") -> None:
    """Checks 2 and 3 of the module docstring for the motion from ``start`` to ``end`` (s) once ``running``
    (absolute start) replaces the follower's command. Before a future start the replaced command runs on: its
    path is checked with the new one (the poses follow the path from ``start_pose``, the platform's pose at
    ``start``); its stop reserve was checked when it came (a stop drops a command still waiting to start)."""
    trial = copy.copy(follower)
    trial.replace(running, start)
    knots = [running.start, *(running.start + running.times)]
    check_strut_path(robot, lambda t: trial.sample(t)[0], start, end, knots=knots, start_pose=start_pose, what=what)
    check_stop_reserve(trial.sample, max(start, running.start), end, knots, robot.limits.strut_acceleration_max,
                       what=what, rest_at=running.end)
