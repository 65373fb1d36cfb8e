"""Kinematics of the 6-UPS platform (batched numpy): rotations, leg geometry, inverse and forward
kinematics, the Jacobian, the limit checks and the legs' own motion.

- ``rotations``: roll-pitch-yaw (paper eq. 3), rotation vectors, quaternions;
- ``geometry``: leg vectors d_i = p + R a_i - b_i (eq. 4), joint angles;
- ``ik``: poses -> strut lengths (eq. 5), ``check_pose``;
- ``fk`` / ``fk_scalar``: strut lengths -> poses (Newton on SO(3), batched / one warm-started solve);
- ``jacobian``: rows [n_i, (R a_i) x n_i] and the homogeneous condition number;
- ``limits``: where stroke, joint and conditioning limits are checked;
- ``legs``: strut rates, leg angular velocities and accelerations from the platform motion.
"""

from .fk import ForwardKinematicsResult, forward_kinematics
from .geometry import cross, joint_angles, leg_vectors, leg_vectors_from_rotation
from .ik import check_pose, inverse_kinematics
from .jacobian import condition_number, jacobian, jacobian_from_vectors

__all__ = [
    "ForwardKinematicsResult",
    "check_pose",
    "condition_number",
    "cross",
    "forward_kinematics",
    "inverse_kinematics",
    "jacobian",
    "jacobian_from_vectors",
    "joint_angles",
    "leg_vectors",
    "leg_vectors_from_rotation",
]
