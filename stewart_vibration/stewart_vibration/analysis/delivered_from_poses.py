"""What a running vibration delivers, from the pose estimate alone (pure): the platform's motion as estimated,
and the legs' hinge-to-hinge lengths that pose implies -- their vibration is the units' (the struts hold still),
so the legs' phases need no second 500 Hz stream."""

from __future__ import annotations

import numpy as np

from ..errors import StewartError
from ..kinematics import inverse_kinematics
from ..robot import Robot
from ..vibration.decompose import VibrationDecomposition
from .delivered import UNKNOWN, DeliveredVibration, delivered_vibration


def delivered_from_poses(robot: Robot, stamps, poses, plan: VibrationDecomposition) -> DeliveredVibration:
    """The vibration the estimated poses (N, 6) (m, rad, base frame) at ``stamps`` (N,) (s) show against
    ``plan`` (analysis.delivered.delivered_vibration); UNKNOWN when a pose is not finite."""
    poses = np.asarray(poses, dtype=float)
    try:
        lengths = inverse_kinematics(robot, poses, check_limits=False)
        return delivered_vibration(stamps, poses[:, :3], stamps, lengths, plan.frequency, plan.direction,
                                   plan.leg_amplitudes, plan.leg_phases)
    except StewartError:  # a non-finite sample: say nothing this time
        return UNKNOWN
