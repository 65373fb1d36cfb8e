"""stewart_vibration: kinematics, vibration planning and dynamics of a 6-UPS
tibia fracture reduction robot with a linear vibration unit on each leg.

The core (this package minus ``stewart_vibration.nodes``) is pure numpy and
never imports rclpy; the ROS 2 nodes in ``stewart_vibration.nodes`` are thin
adapters over it. SI units, base/platform frames, pose = [x, y, z, roll,
pitch, yaw] with R = Rz(yaw) Ry(pitch) Rx(roll).
"""

from .dynamics.newton_euler import Friction, LegForceResult, leg_forces, leg_forces_paper
from .dynamics.platform_trajectory import SinusoidalTrajectory, twist_from_euler_rates, vibration_trajectory
from .errors import (
    ConfigError,
    ForwardKinematicsError,
    InvalidInputError,
    JointLimitError,
    SingularPoseError,
    StewartError,
    StrokeLimitError,
    UnreachablePoseError,
    VibrationLimitError,
)
from .kinematics import (
    ForwardKinematicsResult,
    check_pose,
    condition_number,
    forward_kinematics,
    inverse_kinematics,
    jacobian,
    joint_angles,
    leg_vectors,
)
from .kinematics.robot_config import load_robot
from .kinematics.rotations import (
    euler_rate_matrix,
    pose_from_position_quaternion,
    pose_to_position_quaternion,
    quaternion_from_rpy,
    rotation_from_rpy,
    rpy_from_quaternion,
    rpy_from_rotation,
)
from .robot import Robot
from .sim.mjcf import build_mjcf
from .vibration import (
    MotionClassification,
    SuperpositionResult,
    VibrationDecomposition,
    decompose_vibration,
    platform_vibration_motion,
    sample_leg_vibration,
    superpose_vibration,
)

__all__ = [
    "Friction", "LegForceResult", "SinusoidalTrajectory", "build_mjcf", "leg_forces", "leg_forces_paper",
    "twist_from_euler_rates", "vibration_trajectory",
    "ConfigError",
    "ForwardKinematicsError",
    "ForwardKinematicsResult",
    "InvalidInputError",
    "JointLimitError",
    "Robot",
    "SingularPoseError",
    "StewartError",
    "StrokeLimitError",
    "UnreachablePoseError",
    "VibrationLimitError",
    "check_pose",
    "condition_number",
    "euler_rate_matrix",
    "forward_kinematics",
    "inverse_kinematics",
    "jacobian",
    "joint_angles",
    "leg_vectors",
    "load_robot",
    "pose_from_position_quaternion",
    "pose_to_position_quaternion",
    "quaternion_from_rpy",
    "rotation_from_rpy",
    "rpy_from_quaternion",
    "rpy_from_rotation",
    # vibration
    "MotionClassification",
    "SuperpositionResult",
    "VibrationDecomposition",
    "decompose_vibration",
    "platform_vibration_motion",
    "sample_leg_vibration",
    "superpose_vibration",
]
