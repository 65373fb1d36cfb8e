"""Pose estimates from a stream of measured leg lengths (pure): forward kinematics of each batch.

Every state of a batch starts its Newton iteration at the newest estimate (consecutive states lie close
together, so a few iterations do); before the first estimate, and after a batch none of whose states solved,
at home (a cold start: an estimate that went astray is not the start of the next). A state counts when its
FK converged to the robot's own assembly mode. Lengths in m; poses (6,) [x, y, z, roll, pitch, yaw] in m and
rad in the base frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..robot import Robot
from .fk import forward_kinematics


@dataclass(frozen=True)
class SolvedStates:
    """A batch solved: ``ok`` [n] which states gave a pose, ``poses`` [ok.sum(), 6] theirs, in order."""

    ok: np.ndarray
    poses: np.ndarray


class PoseTracker:
    """Leg lengths in (``solve``), the newest pose estimate (``pose``, None before any) and how many states
    did not solve (``failures``) out."""

    def __init__(self, robot: Robot):
        self.robot = robot
        self.pose: np.ndarray | None = None
        self.failures = 0

    def solve(self, lengths) -> SolvedStates:
        """The poses of leg lengths [n, 6] (m, as the sensors read them: strut plus unit). Raises the FK's
        StewartError (the estimate unchanged) for lengths it cannot start from (not finite, not positive)."""
        lengths = np.asarray(lengths, float)
        guess = self.robot.home_pose if self.pose is None else self.pose
        result = forward_kinematics(self.robot, lengths, guess=np.broadcast_to(guess, lengths.shape),
                                    check_limits=False)
        ok = result.converged & result.assembly_ok
        self.failures += int((~ok).sum())
        poses = result.pose[ok]
        self.pose = poses[-1] if len(poses) else None
        return SolvedStates(ok, poses)
