"""Leg-force estimation (pure numpy): platform motion from leg space (``motion``) and the
estimator's per-run state (``session.ForceEstimator``)."""

from .motion import external_wrench, platform_accel, platform_twist
from .session import ForceEstimate, ForceEstimator, RunningForceError

__all__ = [
    "ForceEstimate",
    "ForceEstimator",
    "RunningForceError",
    "external_wrench",
    "platform_accel",
    "platform_twist",
]
