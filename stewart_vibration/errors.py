"""Typed errors of the stewart_vibration core.

Every error says what is wrong and, where it applies, which leg (1..6) and
which batch sample. Input errors are also ``ValueError`` so generic callers
can catch them.
"""

from __future__ import annotations


class StewartError(Exception):
    """Base class of every error raised by the core library."""


class ConfigError(StewartError, ValueError):
    """The robot configuration file is missing a field or has a bad value."""


class InvalidInputError(StewartError, ValueError):
    """An argument has the wrong shape, is not finite, or is out of its domain."""


class UnreachablePoseError(StewartError, ValueError):
    """A pose (or leg length set) the robot cannot take.

    Attributes: ``leg`` (1..6 or None), ``sample`` (flat batch index or None),
    ``value``, ``limit`` and ``excess`` (how far past the limit, in the
    limit's unit).
    """

    def __init__(self, message: str, *, leg=None, sample=None, value=None, limit=None):
        super().__init__(message)
        self.leg = leg
        self.sample = sample
        self.value = value
        self.limit = limit
        self.excess = None if value is None or limit is None else abs(value - limit)


class StrokeLimitError(UnreachablePoseError):
    """A leg length lies outside [stroke_min_m, stroke_max_m]."""


class JointLimitError(UnreachablePoseError):
    """A universal (base) or spherical (platform) joint angle exceeds its limit."""


class SingularPoseError(UnreachablePoseError):
    """The pose is at or near a singularity (Jacobian condition number too high)."""


class ForwardKinematicsError(StewartError):
    """Newton forward kinematics did not converge or found another assembly mode."""


class LimitExceededError(StewartError, ValueError):
    """A command exceeds a hardware limit.

    Attributes: ``leg`` (1..6 or None), ``limit_name``, ``value``, ``limit``.
    """

    def __init__(self, message: str, *, leg=None, limit_name=None, value=None, limit=None):
        super().__init__(message)
        self.leg = leg
        self.limit_name = limit_name
        self.value = value
        self.limit = limit


class VibrationLimitError(LimitExceededError):
    """A vibration request exceeds a vibration-unit or stroke limit."""


class ActuatorLimitError(LimitExceededError):
    """A strut command exceeds an actuator limit (velocity, force) or the emulator is stopped."""
