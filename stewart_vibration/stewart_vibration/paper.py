"""The paper's worked example (section 4.2), in SI units.

The paper gives X = Y = Z = 2 (mm, offsets from home), roll = pi/15,
pitch = pi/12, yaw = pi/18, and a platform vibration along the force line
0.001 sin(2 t + 2 pi / 3) mm, i.e. 1 um at 2 rad/s with phase 2 pi / 3.
The clinical default is 35 Hz at 0.3 g.
"""

from __future__ import annotations

import numpy as np

from .robot import Robot

PAPER_OFFSET = np.array([0.002, 0.002, 0.002, np.pi / 15, np.pi / 12, np.pi / 18])
PAPER_AMPLITUDE_M = 1e-6
PAPER_OMEGA_RAD_S = 2.0
PAPER_FREQUENCY_HZ = PAPER_OMEGA_RAD_S / (2 * np.pi)
PAPER_PHASE_RAD = 2 * np.pi / 3
CLINICAL_FREQUENCY_HZ = 35.0
CLINICAL_ACCELERATION_G = 0.3


def paper_pose(robot: Robot) -> np.ndarray:
    """The paper's pose: home + [2 mm, 2 mm, 2 mm, pi/15, pi/12, pi/18]."""
    return robot.home_pose + PAPER_OFFSET
