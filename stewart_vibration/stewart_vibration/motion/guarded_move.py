"""A force-guarded reduction move and what the guard decides about it (pure numpy).

Moves are minimum-jerk from rest: L(t) = L0 + D phi(s), s = (t - t0) / T, phi(s) = 10 s^3 - 15 s^4 + 6 s^5, so
every strut moves along the same straight line in leg space and the move's state is one number, its progress
sigma = phi(s) in [0, 1] (sigma of measured lengths: the projection of L - L0 on D). The move's start t0 in the
emulator's clock is first estimated (newest joint state + the expected command delay) and then calibrated from
the measured lengths once the struts move. Times are s of the emulator's clock, lengths m, poses
[x, y, z, roll, pitch, yaw] (m, rad, base frame).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..kinematics.rotations import rotation_from_rpy, so3_log
from ..robot import Robot
from ..splines import smoothstep

AT_REST_SPEED_M_S = 1e-4  # a move planned slower than this (strut, m/s) and ...
AT_REST_ACCEL_M_S2 = 1e-3  # ... accelerating less than this (m/s^2) takes a new target (from rest)
ON_MOVE_PROGRESS_TOL = 0.005  # measured progress this close to the move's plan: the struts still follow it
ON_MOVE_RATE_TOL = 0.2  # ... and their progress rate within this fraction of the planned one (of its peak, near rest)
ON_MOVE_SPAN_S = 0.03  # the measured progress rate: the slope over this much of the newest states (s)
PEAK_RATE_PER_DURATION = 1.875  # a minimum-jerk move's peak progress rate is 1.875 / T

_S_TABLE = np.linspace(0.0, 1.0, 2001)
_PHI_TABLE = smoothstep(_S_TABLE)[0]


def pose_direction(robot: Robot, start, goal) -> np.ndarray:
    """Pose-space displacement start -> goal (6,): [dp (m), rotation vector x characteristic length (m)].

    Args:
        robot: the robot (its characteristic length L, m).
        start: start pose (6,) (m, rad).
        goal: goal pose (6,) (m, rad).

    Returns:
        [p_goal - p_start, L log(R_goal R_start^T)] (6,) (m; base frame).
    """
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    phi = so3_log(rotation_from_rpy(goal[3:]) @ rotation_from_rpy(start[3:]).T)
    return np.concatenate([goal[:3] - start[:3], phi * robot.characteristic_length])


@dataclass(frozen=True)
class StopPlan:
    """Where and how the struts stop: one point (lengths (6,) m, at rest) ``duration`` s after the stop
    arrives; progress sigma_f of the move; receipt_time (s, estimated); peak_accel (m/s^2, worst strut
    over the receipt window)."""

    duration: float
    lengths: np.ndarray
    progress: float
    receipt_time: float
    peak_accel: float


@dataclass(frozen=True)
class GuardTrip:
    """A trip: time (s, emulator clock: the newest estimate's stamp, or the newest state's when a state
    update tripped it), force and moment magnitudes then (N, N m), the predicted
    ones at the end of the stop, which limit ("force" | "moment" | "estimates": none fresh enough), the stop
    (None: the move ends first), the tripped move's goal pose and direction (pose space, unit), and for
    "estimates" what was missing."""

    time: float
    force: float
    moment: float
    predicted_force: float
    predicted_moment: float
    which: str
    stop: StopPlan | None
    goal_pose: np.ndarray
    direction: np.ndarray
    detail: str = ""
    limit: float = 0.0  # the limit that tripped (N or N m; 0 for "estimates")


@dataclass
class GuardedMove:
    """A minimum-jerk move from rest: start time t0 (s, emulator clock, estimated), duration T (s), start and
    goal strut lengths (6,), start and goal poses (6,)."""

    start_time: float
    duration: float
    start_lengths: np.ndarray
    goal_lengths: np.ndarray
    start_pose: np.ndarray
    goal_pose: np.ndarray
    baseline: tuple | None = None  # force and moment magnitudes at the move's start (its first estimate)
    calibrated: bool = False
    stopped: bool = False  # a trip or a cancel sent its stop: the move ends there
    stop: StopPlan | None = None  # a cancel's stop (a trip's is the trip's): ``end`` is its end
    force_limit: float | None = None  # this move's own limits (N, N m; None = the guard's)
    moment_limit: float | None = None
    samples: list = field(default_factory=list)  # (t, sigma, |F|, |M|) of the estimates during the move

    @property
    def delta(self) -> np.ndarray:
        """Strut length change goal - start (6,), m: the move's line in leg space."""
        return self.goal_lengths - self.start_lengths

    @property
    def stroke(self) -> float:
        """The longest strut travel of the move, max |delta| (m): the scale of its progress in leg space."""
        return float(np.abs(self.delta).max())

    @property
    def end(self) -> float:
        """The move's end (s, emulator clock): the end of a cancel's stop, else of the planned move."""
        if self.stop is not None:
            return self.stop.receipt_time + self.stop.duration
        return self.start_time + self.duration

    def progress(self, times):
        """(sigma, sigma_dot, sigma_ddot) at emulator times [n] (s)."""
        s = (np.asarray(times, float) - self.start_time) / self.duration
        phi, d1, d2 = smoothstep(s)
        inside = (s > 0) & (s < 1)
        return phi, np.where(inside, d1 / self.duration, 0.0), np.where(inside, d2 / self.duration**2, 0.0)

    def measured_progress(self, lengths) -> np.ndarray:
        """sigma [n] of measured strut lengths [n, 6] (projection on the move's line)."""
        d = self.delta
        return (np.asarray(lengths, float) - self.start_lengths) @ d / max(float(d @ d), 1e-300)

    def calibrate(self, times, lengths) -> float | None:
        """Fix t0 from the first measured state at clearly nonzero progress (the emulator started the move
        when it received it, which the node only estimates); returns the correction (s) when it does."""
        if self.calibrated:
            return None
        sigma = self.measured_progress(lengths)
        good = np.flatnonzero((sigma > 0.02) & (sigma < 0.6))
        if not good.size:
            return None
        k = good[0]
        s = np.interp(sigma[k], _PHI_TABLE, _S_TABLE)
        start = float(times[k]) - s * self.duration
        correction, self.start_time, self.calibrated = start - self.start_time, start, True
        return correction

    def under_way(self, now: float) -> float | None:
        """The move's end (s) while it is pending or running at ``now`` (s), or None: it has ended, a trip or
        cancel stopped it, it is a move of nothing (planned peak strut speed below AT_REST_SPEED_M_S), or it is in
        its second half and at rest already (planned strut speed and acceleration below AT_REST_SPEED_M_S and
        AT_REST_ACCEL_M_S2: its end). Before its estimated start and while still at rest at its start it counts as
        under way: the struts may depart any moment (the emulator takes a command when it gets it)."""
        if self.stopped or now >= self.end:
            return None
        scale = self.stroke
        if PEAK_RATE_PER_DURATION * scale / self.duration < AT_REST_SPEED_M_S:
            return None
        _, rate, accel = (float(x[0]) for x in self.progress([now]))
        past_middle = now >= self.start_time + 0.5 * self.duration
        if past_middle and abs(rate) * scale < AT_REST_SPEED_M_S and abs(accel) * scale < AT_REST_ACCEL_M_S2:
            return None
        return self.end

    def followed_by(self, times, progress) -> bool:
        """Whether measured states (stamps [n] s, progress [n]) still follow the move as planned: the newest
        progress within ON_MOVE_PROGRESS_TOL of the plan at its stamp, and the progress rate (slope over
        ON_MOVE_SPAN_S) within ON_MOVE_RATE_TOL of the planned rate. A stop the emulator took, however late,
        bends them off the plan (first in rate); a stop that never took leaves them on it."""
        t, sigma = np.asarray(times, float), np.asarray(progress, float)
        if not t.size:
            return True
        recent = t >= t[-1] - ON_MOVE_SPAN_S
        planned, rate, _ = self.progress(t[recent])
        if abs(float(sigma[-1] - planned[-1])) > ON_MOVE_PROGRESS_TOL:
            return False
        if np.count_nonzero(recent) < 3:
            return True
        measured_rate = float(np.polyfit(t[recent], sigma[recent], 1)[0])
        planned_rate = float(rate.mean())
        floor = ON_MOVE_RATE_TOL * PEAK_RATE_PER_DURATION / self.duration
        return abs(measured_rate - planned_rate) <= max(ON_MOVE_RATE_TOL * abs(planned_rate), floor)
