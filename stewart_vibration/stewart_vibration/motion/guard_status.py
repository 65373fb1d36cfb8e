"""The force guard's status as plain values (pure): what kinematics/guard_status carries and its readers get."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

GUARD_STATES = ("armed", "tripped", "off")  # index = ForceGuardStatus state constant
TRIP_LIMITS = ("", "force", "moment", "estimates")  # index = ForceGuardStatus LIMIT_* constant


@dataclass(frozen=True)
class GuardStatus:
    """The force guard armed with its limits, off (both 0), or tripped: the trip (time s of the robot's clock,
    the limit and the load then, N and N m), what it predicted at the goal, the peak load while stopping, the
    stop (duration s, 0 when the move ended first; where it brings the move, 0 start .. 1 goal), the tripped
    goal (6,) [x, y, z, roll, pitch, yaw] (m, rad, base frame) and direction (6,) (pose space, unit) and how many
    directions are refused until reset. Every trip value is NaN (and the poses NaN) when not tripped."""

    state: str
    force_limit_n: float
    moment_limit_nm: float
    message: str = ""
    trip_limit: str = ""
    trip_time_s: float = float("nan")
    trip_force_n: float = float("nan")
    trip_moment_nm: float = float("nan")
    predicted_force_n: float = float("nan")
    predicted_moment_nm: float = float("nan")
    peak_force_n: float = float("nan")
    peak_moment_nm: float = float("nan")
    stop_duration_s: float = float("nan")
    stop_progress: float = float("nan")
    tripped_goal: np.ndarray = field(default_factory=lambda: np.full(6, np.nan))
    tripped_direction: np.ndarray = field(default_factory=lambda: np.full(6, np.nan))
    blocked_directions: int = 0

    @property
    def tripped(self) -> bool:
        """True while a trip is latched."""
        return self.state == "tripped"

    def record(self) -> dict:
        """Plain values for a run record or JSON (NaN as None, poses as lists)."""
        def value(x):
            if isinstance(x, np.ndarray):
                return [None if not np.isfinite(v) else float(v) for v in x]
            if isinstance(x, float) and not np.isfinite(x):
                return None
            return x
        return {name: value(getattr(self, name)) for name in self.__dataclass_fields__}
