"""The 42 kinematic parameters a calibration identifies, as one vector, and the robot they describe.

Order: base hinges B_1..B_6 (x, y, z, base frame, m), platform hinges A_1..A_6 (x, y, z, platform frame,
m), strut zero offsets d_1..d_6 (m; encoder = hinge-to-hinge length - d). The base and platform frames are
the tracker's: it reports the platform frame's pose in the base frame, so the frame convention fixes none
of the 42 and all are identifiable from tracker poses that turn the platform about every axis.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..robot import Robot

PARAMETER_COUNT = 42
BASE = slice(0, 18)
PLATFORM = slice(18, 36)
OFFSETS = slice(36, 42)


def parameter_names() -> tuple[str, ...]:
    """Names of the 42 parameters, in vector order ("base_hinge_1_x", ..., "strut_zero_offset_6")."""
    hinges = [f"{part}_hinge_{leg}_{axis}" for part in ("base", "platform") for leg in range(1, 7) for axis in "xyz"]
    return tuple(hinges + [f"strut_zero_offset_{leg}" for leg in range(1, 7)])


def parameters_of(robot: Robot) -> np.ndarray:
    """The robot's parameter vector (42,) m."""
    return np.concatenate([robot.base_hinges.ravel(), robot.platform_hinges.ravel(), robot.strut_zero_offsets])


def split_parameters(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(base hinges (6, 3), platform hinges (6, 3), strut zero offsets (6,)) of a parameter vector (42,)."""
    theta = np.asarray(theta, float)
    return theta[BASE].reshape(6, 3), theta[PLATFORM].reshape(6, 3), theta[OFFSETS]


def robot_with_parameters(robot: Robot, theta: np.ndarray, source: str = "") -> Robot:
    """``robot`` with the hinges and strut zero offsets of ``theta`` (42,), marked calibrated."""
    base, platform, offsets = split_parameters(theta)
    return replace(robot, base_hinges=base, platform_hinges=platform, strut_zero_offsets=offsets, calibrated=True,
                   source=source or robot.source)
