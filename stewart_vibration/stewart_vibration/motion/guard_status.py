"""The force guard's status as plain values (pure): what kinematics/guard_status carries and its readers get,
and its one-line message for the log and /diagnostics."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # the trip type only: readers of a status need none of the guard's math
    from .guarded_move import GuardTrip

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


def trip_figures(trip: GuardTrip) -> str:
    """The load that tripped and its limit (N, N m), or for "estimates" what was missing."""
    if trip.which == "estimates":
        return trip.detail
    if trip.which == "force":
        return f"{trip.force:.1f} N, predicted {trip.predicted_force:.1f} N > the force limit {trip.limit:g} N"
    return f"{trip.moment:.2f} N m, predicted {trip.predicted_moment:.2f} N m > the moment limit {trip.limit:g} N m"


def guard_message(trip: GuardTrip | None, force_limit: float, moment_limit: float) -> str:
    """One line: armed with the guard's limits (N, N m), or the trip, its stop and the latch."""
    if trip is None:
        return f"armed: guard_force_n {force_limit:g} N, guard_moment_nm {moment_limit:g} N m (0 = off)"
    stop = f"struts stopped over {trip.stop.duration:.2f} s" if trip.stop else "the move ended before a stop"
    return (f"tripped at {trip.time:.3f} s: {trip.which} {trip_figures(trip)}; {stop}; holding; goals "
            "further in that direction are refused until kinematics/reset_guard or a new limit")


def guard_status(trip: GuardTrip | None, force_limit: float, moment_limit: float, message: str,
                 peak: tuple[float, float], blocked_directions: int) -> GuardStatus:
    """The status of a guard watching with these limits (N, N m; both 0: off), latched on ``trip`` (None: not
    tripped) with the peak force and moment since (N, N m) and the number of directions it refuses."""
    if trip is None:
        return GuardStatus("off" if force_limit <= 0 and moment_limit <= 0 else "armed", force_limit, moment_limit,
                           message)
    return GuardStatus(
        "tripped", force_limit, moment_limit, message, trip_limit=trip.which, trip_time_s=trip.time,
        trip_force_n=trip.force, trip_moment_nm=trip.moment, predicted_force_n=trip.predicted_force,
        predicted_moment_nm=trip.predicted_moment, peak_force_n=peak[0], peak_moment_nm=peak[1],
        stop_duration_s=trip.stop.duration if trip.stop else 0.0,
        stop_progress=trip.stop.progress if trip.stop else 1.0,
        tripped_goal=np.array(trip.goal_pose, float), tripped_direction=np.array(trip.direction, float),
        blocked_directions=blocked_directions)
