"""Vibration superposition and decomposition (paper section 4, with the corrections in docs/dynamics.md).

decompose: platform vibration -> six leg vibration equations (gains, phases,
exact IK signals); superpose: six leg vibrations -> platform motion (exact
FK and J^-1) with its classification; signals: ramped leg commands and the
planned platform motion for the ROS planner and the force estimator.
"""

from .classify import MotionClassification, classify_motion, common_period
from .decompose import VibrationDecomposition, decompose_vibration
from .screw import VibrationScrew
from .signals import LegVibrationSamples, PlatformVibrationMotion, platform_vibration_motion, sample_leg_vibration
from .superpose import SuperpositionResult, naive_superposition, superpose_vibration
from .waveform import acceleration_from_displacement, displacement_from_acceleration, envelope

__all__ = [
    "LegVibrationSamples",
    "MotionClassification",
    "PlatformVibrationMotion",
    "SuperpositionResult",
    "VibrationDecomposition",
    "VibrationScrew",
    "acceleration_from_displacement",
    "classify_motion",
    "common_period",
    "decompose_vibration",
    "displacement_from_acceleration",
    "envelope",
    "naive_superposition",
    "platform_vibration_motion",
    "sample_leg_vibration",
    "superpose_vibration",
]
