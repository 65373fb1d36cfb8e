"""How big a command the emulated robot takes (pure): points per leg trajectory and per vibration window,
and the message bytes that can carry them -- checked before anything big is allocated.

Why these numbers (measured on the 2-core suite machine, see benchmarks/strut_acceptance.py):

- MAX_TRAJECTORY_POINTS = 5,000 leg-trajectory points: the kinematics node sends one point per
  trajectory_sample_period_s (20 ms by default: a 10 s move has 500, a 100 s move the bound) and thins longer
  moves to it. Checking costs ~50 us a point here (per strut, the workspace along it, its stop reserve):
  ~0.25 s for a maximal command, on the executor thread, outside the physics lock (held ~0.2 ms for it), and
  ~1 MB to hold in the emulator and the estimator. The 1,000,000-point command that stalled physics for 20 s
  (and took 4 GB) is refused from its size.
- MAX_WINDOW_POINTS: the vibration planner's own bound on a window (vibration.settings.MAX_WINDOW_SAMPLES):
  every window it can legally send is taken; a longer one never comes from it.
- The byte bounds allow every field of every point (positions, velocities, accelerations, effort of 6
  joints: at most 232 bytes a point in CDR) plus the header: a message longer than that cannot be a command
  within the point bound and is refused before it is decoded (``raw_command_refusal``).
"""

from __future__ import annotations

from ..errors import ActuatorLimitError, VibrationLimitError
from ..vibration.settings import MAX_WINDOW_SAMPLES

MAX_TRAJECTORY_POINTS = 5_000
MAX_WINDOW_POINTS = MAX_WINDOW_SAMPLES
POINT_BYTES = 4 * (8 + 6 * 8) + 8  # four float64 sequences of 6 (length + padding + values) + time_from_start
HEADER_BYTES = 4096  # CDR header, stamp, frame id and 6 joint names (names of at most ~600 characters)
LEG_TRAJECTORY = "leg trajectory"
VIBRATION_WINDOW = "vibration window"
MAX_POINTS = {LEG_TRAJECTORY: MAX_TRAJECTORY_POINTS, VIBRATION_WINDOW: MAX_WINDOW_POINTS}


def max_message_bytes(kind: str) -> int:
    """The longest serialized JointTrajectory (bytes) that can carry a ``kind`` command within its point bound."""
    return HEADER_BYTES + MAX_POINTS[kind] * POINT_BYTES


def raw_command_refusal(data, kind: str) -> str | None:
    """Why a serialized JointTrajectory of ``kind`` (LEG_TRAJECTORY or VIBRATION_WINDOW) is refused before
    it is decoded (its byte length alone), or None. For the node's raw subscriptions: call it first."""
    size, limit = len(data), max_message_bytes(kind)
    if size > limit:
        return (f"the {kind} message has {size} bytes; at most {limit} ({MAX_POINTS[kind]} points): send shorter "
                "commands")
    return None


def check_point_count(count: int, kind: str) -> None:
    """Raise the typed refusal of a ``kind`` command with ``count`` points beyond its bound.

    Raises:
        ActuatorLimitError (leg trajectory) / VibrationLimitError (vibration window): ``limit_name``
            "max_points", ``value`` the count, ``limit`` the bound.
    """
    limit = MAX_POINTS[kind]
    if count > limit:
        error = ActuatorLimitError if kind == LEG_TRAJECTORY else VibrationLimitError
        raise error(f"the {kind} has {count} points; at most {limit}: send shorter commands",
                    limit_name="max_points", value=float(count), limit=float(limit))
