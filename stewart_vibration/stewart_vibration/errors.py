"""Typed errors of the stewart_vibration core.

Every error says what is wrong and, where it applies, which leg (1..6) and
which batch sample. Input errors are also ``ValueError`` so generic callers
can catch them. Each class names its ``outcome``: the name of its code in the suite's one outcome table
(stewart_vibration_interfaces/msg/Outcome, docs/interfaces.md), which nodes put in their typed answers.
"""

from __future__ import annotations


class StewartError(Exception):
    """Base class of every error raised by the core library."""

    outcome = "INTERNAL_ERROR"


class RefusedError(StewartError):
    """A request refused with a given ``outcome`` (a name of the outcome table, e.g. "BUSY", "NOT_READY")."""

    def __init__(self, outcome: str, message: str):
        super().__init__(message)
        self.outcome = outcome


class ConfigError(StewartError, ValueError):
    """The robot configuration file is missing a field or has a bad value."""

    outcome = "INVALID_ARGUMENT"


class InvalidInputError(StewartError, ValueError):
    """An argument has the wrong shape, is not finite, or is out of its domain."""

    outcome = "INVALID_ARGUMENT"


class UnreachablePoseError(StewartError, ValueError):
    """A pose (or leg length set) the robot cannot take.

    Attributes: ``leg`` (1..6 or None), ``sample`` (flat batch index or None),
    ``value``, ``limit`` and ``excess`` (how far past the limit, in the
    limit's unit); along a path also ``limit_name`` (e.g. "universal_joint_max") and ``time`` (s, when
    the path reaches the violation).
    """

    outcome = "UNREACHABLE_POSE"

    def __init__(self, message: str, *, leg=None, sample=None, value=None, limit=None, limit_name=None,
                 time=None):
        super().__init__(message)
        self.leg = leg
        self.sample = sample
        self.value = value
        self.limit = limit
        self.limit_name = limit_name
        self.time = time
        self.excess = None if value is None or limit is None else abs(value - limit)


class StrokeLimitError(UnreachablePoseError):
    """A leg length lies outside [stroke_min_m, stroke_max_m]."""


class JointLimitError(UnreachablePoseError):
    """A universal (base) or spherical (platform) joint angle exceeds its limit."""


class SingularPoseError(UnreachablePoseError):
    """The pose is at or near a singularity (Jacobian condition number too high)."""


class ForwardKinematicsError(StewartError):
    """Newton forward kinematics did not converge or found another assembly mode."""

    outcome = "NOT_READY"  # no usable pose from the measured lengths


class LimitExceededError(StewartError, ValueError):
    """A command exceeds a hardware limit.

    Attributes: ``leg`` (1..6 or None), ``limit_name``, ``value``, ``limit``, ``time`` (s, when a command
    reaches the limit, or None).
    """

    outcome = "LIMIT_EXCEEDED"

    def __init__(self, message: str, *, leg=None, limit_name=None, value=None, limit=None, time=None):
        super().__init__(message)
        self.leg = leg
        self.limit_name = limit_name
        self.value = value
        self.limit = limit
        self.time = time


class VibrationLimitError(LimitExceededError):
    """A vibration request exceeds a vibration-unit or stroke limit."""


class ActuatorLimitError(LimitExceededError):
    """A strut command exceeds an actuator limit (velocity, force) or the emulator is stopped."""


class TissueLimitError(ActuatorLimitError):
    """The tissue model predicts a strut force above strut_force_max on a waypoint (``waypoint``: its index)."""

    outcome = "TISSUE_LIMIT"

    def __init__(self, message: str, *, waypoint=None, **limits):
        super().__init__(message, **limits)
        self.waypoint = waypoint


class GuardBlockedError(ActuatorLimitError):
    """A target further along the direction of a move the force guard stopped (until it is reset)."""

    outcome = "GUARD_BLOCKED"


class EmergencyStopLatchedError(ActuatorLimitError):
    """A motion command while the emergency stop is latched (limit_name "emergency_stop")."""

    outcome = "ESTOP_LATCHED"


class MalformedMessageError(InvalidInputError):
    """A received message (or service answer) that cannot be read: a field missing, of the wrong type, not
    finite, out of its range, a bad string (NUL, control characters, not UTF-8, too long), a wrong array
    length or name, or bytes that are not the message type.

    Attributes: ``field`` (the field or key, or None for the whole message) and ``kind`` (one of
    "structure", "missing", "type", "not_finite", "range", "text", "length", "names", "frame"). ``reason``
    (kind and field) names the class of fault without its value, for counting and rate-limited logs.
    """

    def __init__(self, message: str, *, field: str | None = None, kind: str = "structure"):
        super().__init__(message)
        self.field = field
        self.kind = kind

    @property
    def reason(self) -> str:
        """``kind`` and ``field`` (e.g. "type rejections"): the fault's class, without the offending value."""
        return f"{self.kind} {self.field}" if self.field else self.kind


class PhysicsFaultError(StewartError):
    """The emulated robot's physics diverged: the fault is latched and the robot held (see
    ``emulation.physics_guard``). Attributes: ``time`` (s, sim time of the fault) and ``reason``."""

    outcome = "PHYSICS_FAULT"

    def __init__(self, message: str, *, time=None, reason=""):
        super().__init__(message)
        self.time = time
        self.reason = reason


class CalibrationError(StewartError):
    """Calibration data that cannot give a trustworthy robot file; ``reason`` is one of TOO_FEW_POSES,
    UNIDENTIFIABLE, TOO_MANY_OUTLIERS, TRACKER_FROZEN, BAD_DATA."""

    outcome = "CALIBRATION_REJECTED"

    def __init__(self, reason: str, message: str):
        super().__init__(message)
        self.reason = reason
