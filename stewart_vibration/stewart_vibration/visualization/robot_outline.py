"""The robot as lines and points at one platform pose (pure numpy), for the emulator's robot_markers: what a
3D panel needs to show the robot without /tf. Every array is in the base frame, m."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kinematics.rotations import rotation_from_quaternion
from ..robot import Robot


@dataclass(frozen=True)
class RobotOutline:
    """``legs`` (12, 3): base hinge B_i then platform hinge A_i of each leg (a line list); ``platform`` (7, 3)
    and ``base`` (7, 3): the hinges in order, back to the first (closed line strips); ``hinges`` (12, 3):
    the six base hinges, then the six platform hinges."""

    legs: np.ndarray
    platform: np.ndarray
    base: np.ndarray
    hinges: np.ndarray


def robot_outline(robot: Robot, position, quaternion) -> RobotOutline:
    """The outline of ``robot`` with its platform at ``position`` (3,) m and ``quaternion`` (4,) [x, y, z, w],
    both in base."""
    tips = np.asarray(position, dtype=float) + robot.platform_hinges @ rotation_from_quaternion(quaternion).T
    base = robot.base_hinges
    return RobotOutline(legs=np.stack([base, tips], axis=1).reshape(-1, 3), platform=np.vstack([tips, tips[:1]]),
                        base=np.vstack([base, base[:1]]), hinges=np.vstack([base, tips]))
