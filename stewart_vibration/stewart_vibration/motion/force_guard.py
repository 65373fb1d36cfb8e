"""Force-guarded reduction moves (pure numpy): watch the external-wrench estimate during a move, stop
the struts smoothly before the load passes a limit, hold, and refuse further targets in that direction
until the operator resets the guard or changes the limit. The kinematics node only wires it to topics.

Moves. The kinematics node sends minimum-jerk moves from rest: L(t) = L0 + D phi(s), s = (t - t0) / T,
phi(s) = 10 s^3 - 15 s^4 + 6 s^5, so every strut moves along the same straight line in leg space and the
move's state is one number, its progress sigma = phi(s) in [0, 1] (sigma of measured lengths: the
projection of L - L0 on D). The move's start t0 in the emulator's clock is first estimated (newest joint
state + ``RECEIPT_DELAY_S``) and then calibrated from the measured lengths once the struts move.

Trip. For every batch of wrench estimates and of joint states during a move the guard predicts the load
at the end of the stop it would command now: the force (and moment) magnitude is fitted against the
progress over the last ``FIT_WINDOW_S`` of estimates (quadratic, continued as an exponential with the
fit's local growth rate while the load rises: soft tissue stiffens with distraction) and extrapolated to
the progress at which that stop would end (the travel until the emulator gets the command plus the
braking distance). A state newer than the newest estimate moves that progress on, so estimates that lag
do not delay the trip; the stop is assumed sent at the next check, which comes no sooner than the largest
gap between the recent checks (``check_gap``: a node starved of CPU checks late). It trips when the predicted
force exceeds ``force_limit`` (or the moment ``moment_limit``) and the load has risen above what it was at
the move's start (a move that relieves a load that is already over the limit is not stopped). A limit of 0
switches that check off.

Stop. A leg trajectory stamped 0 (now) with one point: the struts come to rest at L0 + D sigma_f after
T_s. The emulator departs from the state it commands when the stop arrives, which lies on the move at a
receipt time known only within a window after the node's "now" (``RECEIPT_WINDOW_S``, widened to twice
the command delays measured on the moves: each move's start is calibrated from the measured lengths);
the quintic from any such departure to (sigma_f, rest) must stay within ``deceleration_scale`` x
strut_acceleration_max and strut_velocity_max (checked on a grid of receipt times), and T_s is the
shortest that does. If the emulator refuses the stop anyway (it arrived later still) or the measured
struts run past it while still following the move (the stop never took), the node asks ``missed_stop``
for another one over a doubled window; struts past it that have left the move took it late: its quintic
overshoots the end within the limits and returns, and they get no new stop (one planned from the move would
drive them on). sigma_f is the natural stopping point of the estimated departure (velocity falling as a
cubic smoothstep: sigma_f = sigma + T_s (sigma_dot / 2 + sigma_ddot T_s / 12)), so the stop follows the planned path. If
the move would end before the stop could (sigma_f >= 1), no stop is sent: the move ends at its goal.

Blind. The guard is only as good as its input: while a move is under way, a newest wrench estimate
older than ``max_estimate_age`` (s of sim time) behind the newest joint state (the estimator late,
stalled or gone) trips the guard too (limit "estimates"), with the same stop: no estimate, no motion.
That trip is a pause: once the stop is over and estimates have kept up for ``RESUME_FRESH_S``, ``resume_after_blind``
restores the guard as it was before it (the node then sends the interrupted target again) unless the
load it could not see has passed a limit meanwhile: then the trip becomes a force (moment) trip.
Until a first estimate has arrived at all (no estimator running) moves are unguarded; the node warns.
Moves are slowed so that the struts cover at most ``blind_travel`` in the estimates' lag behind the states
(the largest over the last ``LAG_MEMORY_S``, as ``speed_limit`` gives it): a busy machine, on which the
guard sees late, gets slower moves rather than overshoot (after a blind pause the resumed move is slow).

Latch. After a trip the guard holds the direction of the move (pose space, rotations scaled by the
robot's characteristic length): a target whose displacement from the current pose has a component along
it is refused with the reason; other targets (back, sideways) are allowed and watched like any move (a
second trip blocks its direction too). ``reset`` or new limits clear the latch.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import GuardBlockedError
from ..kinematics.rotations import rotation_from_rpy, so3_log
from ..robot import Robot
from ..splines import quintic_hermite, smoothstep
from .guard_status import GuardStatus

RECEIPT_DELAY_S = 0.02  # expected emulator time between the node's estimate of "now" and its command arriving
RECEIPT_WINDOW_S = 0.15  # the stop stays within the limits for any arrival within this (at least) after "now"
FIT_WINDOW_S = 0.15  # estimate history fitted against the progress (s of sim time)
MIN_FIT_SAMPLES = 8
MAX_WINDOW_S = 0.6  # the receipt window never grows beyond this (stops would get long)
STATE_HISTORY_S = 2.0  # measured progress kept for the estimates (which lag the states)
MAX_STOP_RETRIES = 3
STOP_DURATIONS_S = (0.05, 5.0)  # shortest and longest stop (s)
STOP_RESOLUTION_S = 0.01
MAX_EXTRAPOLATION = 5.0  # the fit is extrapolated at most this many times its own span of progress
MAX_GROWTH_EXPONENT = 2.0  # the exponential continuation of the fit grows at most e^2 - 1 times its slope / rate
LAG_MEMORY_S = 3.0  # the estimates' lag behind the states is remembered this long (s of sim time)
BLIND_TRAVEL_M = 1.5e-3  # default: moves are slowed so that the struts cover at most this in the estimates' lag
RESUME_FRESH_S = 0.5  # a blind pause ends once estimates have kept up this long (s of sim time)
CHECK_MEMORY_S = 1.0  # the largest gap between the guard's checks over this much sim time is its look-ahead
MAX_ESTIMATE_AGE_S = 0.25  # default: a move pauses when the newest wrench estimate is this far (s) behind the states
_TAU = np.linspace(0.0, 1.0, 41)  # points per stop segment at which the limits are checked
# quintic Hermite bases on _TAU for a segment of unit duration ending at rest (v1 = a1 = 0): velocity and
# acceleration per unit of (p0 - p1), v0 and a0; a segment of duration h scales them by 1/h, h^0, h
_BASES = [quintic_hermite(_TAU, 1.0, *unit, 0.0, 0.0, 0.0)[1:] for unit in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0),
                                                                          (0.0, 0.0, 1.0))]
DIRECTION_TOLERANCE_M = 1e-6  # a target further along a tripped direction than this (m, pose space) is refused
WATCH_AFTER_S = 0.3  # the guard keeps watching (and recording peaks) this long after a move or stop ends
AT_REST_SPEED_M_S = 1e-4  # a move planned slower than this (strut, m/s) and ...
AT_REST_ACCEL_M_S2 = 1e-3  # ... accelerating less than this (m/s^2) takes a new target (from rest)
ON_MOVE_PROGRESS_TOL = 0.005  # measured progress this close to the move's plan: the struts still follow it
ON_MOVE_RATE_TOL = 0.2  # ... and their progress rate within this fraction of the planned one (of its peak, near rest)
ON_MOVE_SPAN_S = 0.03  # the measured progress rate: the slope over this much of the newest states (s)
ON_MOVE_SETTLE_S = 0.1  # struts judged on the move only this long (s) after the latest a stop could be taken


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


class ForceGuard:
    """See the module docstring. Limits in N and N m (0 = off); deceleration_scale: the fraction of
    strut_acceleration_max a stop may use; max_estimate_age: s of sim time a move goes on without a fresh
    wrench estimate (0 = never stop for that)."""

    _before_blind: tuple[GuardTrip | None, list[np.ndarray], tuple[float, float]] | None
    _fresh_since: float | None
    _delays: list[float]

    def __init__(self, robot: Robot, force_limit: float, moment_limit: float, deceleration_scale: float = 0.8,
                 max_estimate_age: float = MAX_ESTIMATE_AGE_S, blind_travel: float = BLIND_TRAVEL_M):
        self.robot = robot
        self.blind_travel = float(blind_travel)
        self._lags = np.zeros((0, 2))  # (newest state time, its lag behind it of the newest estimate), s
        self.max_estimate_age = float(max_estimate_age)
        self.newest_estimate = -np.inf  # stamp of the newest wrench estimate observed (s)
        self._before_blind = None  # (trip, blocked, peak) before an "estimates" trip: restored when they return
        self._fresh_since = None  # since when (s) the estimates have kept up after an "estimates" trip
        self.force_limit, self.moment_limit = float(force_limit), float(moment_limit)
        self.deceleration_scale = float(deceleration_scale)
        self.move: GuardedMove | None = None
        self.trip: GuardTrip | None = None  # the latest trip (latched until reset)
        self.blocked: list[np.ndarray] = []  # directions of every move stopped since the last reset
        self._stopping: GuardedMove | None = None  # the move the latest trip stopped
        self.peak = (0.0, 0.0)  # largest force and moment magnitudes estimated since the trip
        self.last_wrench = np.zeros(6)  # the newest wrench estimate (N, N m): the load of an "estimates" trip
        self._state_t = np.zeros(0)
        self._state_sigma = np.zeros(0)
        self._stop_retries = 0
        self.receipt_window = RECEIPT_WINDOW_S  # grows with the command delays measured on this robot
        self._delays = []  # measured command delays (s): the move's calibrated start - the node's "now" at sending
        self._checks = np.zeros(0)  # the emulator times (s) at which assess ran, over the last CHECK_MEMORY_S
        self.predicted = (float("nan"), float("nan"))  # the latest prediction of force and moment at a stop's end

    # -- settings ---------------------------------------------------------------------------------
    def set_limits(self, force_limit: float | None = None, moment_limit: float | None = None) -> bool:
        """New limits; a change clears a latched trip (the operator decided). Returns whether it cleared one."""
        changed = (force_limit is not None and float(force_limit) != self.force_limit) or \
            (moment_limit is not None and float(moment_limit) != self.moment_limit)
        if force_limit is not None:
            self.force_limit = float(force_limit)
        if moment_limit is not None:
            self.moment_limit = float(moment_limit)
        return changed and self.reset()

    def reset(self) -> bool:
        """Clear a latched trip; returns whether one was latched."""
        was = self.trip is not None
        self.trip, self.peak, self.blocked, self._stopping = None, (0.0, 0.0), [], None
        self._before_blind = None
        return was

    def robot_stopped(self) -> bool:
        """The robot was stopped outside this guard (the emulator's e-stop, deactivate, shutdown or physics
        fault): the move it watched is over, and a pause for late estimates ends without resuming it (the
        guard is as it was before that pause). Returns whether a move was dropped."""
        dropped = self.move is not None or self._before_blind is not None
        self.move, self._stopping, self._fresh_since = None, None, None
        if self._before_blind is not None:
            self._end_pause()
        return dropped

    @property
    def tripped(self) -> bool:
        """Whether a trip is latched (until reset or new limits)."""
        return self.trip is not None

    # -- moves and targets ----------------------------------------------------------------------------
    def move_under_way(self, now: float) -> float | None:
        """The end (s, emulator clock) of the move sent last while it is pending or running at ``now`` (s), or
        None: no move, it has ended, a trip stopped it, it is a move of nothing (planned peak strut speed below
        AT_REST_SPEED_M_S), or it is in its second half and at rest already (planned strut speed and
        acceleration below AT_REST_SPEED_M_S and AT_REST_ACCEL_M_S2: its end). A target sent while the struts
        move would be planned from rest: the emulator refuses it and runs on, while the guard would watch the
        refused move instead. Before its estimated start and while it is still at rest at its start the move
        counts as under way too: the struts may depart any moment (the emulator takes a command when it gets
        it), and a train of targets each arriving before the last one's start would otherwise all be taken."""
        move = self.move
        if move is None or move.stopped or now >= move.end:
            return None
        scale = move.stroke
        if 1.875 * scale / move.duration < AT_REST_SPEED_M_S:  # 1.875 / T: a minimum-jerk move's peak rate
            return None
        _, rate, accel = (float(x[0]) for x in move.progress([now]))
        past_middle = now >= move.start_time + 0.5 * move.duration
        if past_middle and abs(rate) * scale < AT_REST_SPEED_M_S and abs(accel) * scale < AT_REST_ACCEL_M_S2:
            return None
        return move.end

    def check_target(self, current_pose, target_pose) -> None:
        """Raise GuardBlockedError (limit_name "force_guard") if a trip is latched and the target lies further
        along the direction of a move the guard stopped since the last reset."""
        trip = self.trip
        if trip is None:
            return
        step = pose_direction(self.robot, current_pose, target_pose)
        along = max(float(step @ direction) for direction in self.blocked)
        if along > DIRECTION_TOLERANCE_M:
            raise GuardBlockedError(
                f"force guard tripped at {trip.time:.3f} s ({trip.which} {self._tripped_value(trip)}): a goal "
                f"{along * 1e3:.3f} mm further along the stopped move's direction is refused until "
                "kinematics/reset_guard is called or guard_force_n / guard_moment_nm is changed",
                limit_name="force_guard", value=along, limit=0.0)

    def _tripped_value(self, trip: GuardTrip) -> str:
        if trip.which == "estimates":
            return trip.detail
        if trip.which == "force":
            return f"{trip.force:.1f} N, predicted {trip.predicted_force:.1f} N > the force limit {trip.limit:g} N"
        return f"{trip.moment:.2f} N m, predicted {trip.predicted_moment:.2f} N m > the moment limit {trip.limit:g} N m"

    def begin_move(self, start_time: float, duration: float, start_lengths, goal_lengths, start_pose,
                   goal_pose, force_limit: float | None = None, moment_limit: float | None = None) -> None:
        """A move was sent (estimated start ``start_time`` s, emulator clock): watch it. The load at its start
        (the baseline a trip must rise above) is its first estimate. ``force_limit`` / ``moment_limit``: this
        move's own limits (N, N m; None: the guard's)."""
        self.move = GuardedMove(float(start_time), float(duration), np.asarray(start_lengths, float).copy(),
                                np.asarray(goal_lengths, float).copy(), np.asarray(start_pose, float).copy(),
                                np.asarray(goal_pose, float).copy(), force_limit=force_limit,
                                moment_limit=moment_limit)
        self._state_t, self._state_sigma = np.zeros(0), np.zeros(0)
        self.predicted = (float("nan"), float("nan"))

    def limits(self, move: GuardedMove | None = None) -> tuple[float, float]:
        """The force and moment limits (N, N m; 0 = off) that watch ``move`` (default: the current one)."""
        move = self.move if move is None else move
        force = self.force_limit if move is None or move.force_limit is None else move.force_limit
        moment = self.moment_limit if move is None or move.moment_limit is None else move.moment_limit
        return force, moment

    def cancel(self, newest_state_time: float, attempt: int = 0) -> StopPlan | None:
        """A controlled stop of the current move on request (not a trip: nothing is latched, no direction
        blocked): the stop a trip would command now (within deceleration_scale x strut_acceleration_max, for
        an arrival within the receipt window, doubled per ``attempt`` after the robot refused the last one);
        the move ends there. None if there is no move to stop or it reaches its goal first."""
        move = self.move
        if move is None or (move.stopped and attempt == 0) or attempt > MAX_STOP_RETRIES:
            return None
        stop = self.plan_stop(newest_state_time, window_s=self.receipt_window * 2**attempt)
        move.stop, move.stopped = stop, stop is not None
        return stop

    def observe_states(self, stamps, strut_lengths) -> None:
        """Measured strut lengths [n, 6] at stamps [n] (s): the move's progress (for the fit) and its start."""
        move = self.move
        if move is None:
            return
        stamps = np.asarray(stamps, float)
        correction = move.calibrate(stamps, strut_lengths)
        if correction is not None:  # how late the emulator really took the move, against the estimate
            self._delays = (self._delays + [RECEIPT_DELAY_S + correction])[-5:]
            self.receipt_window = float(np.clip(2.0 * max(self._delays) + 0.05, RECEIPT_WINDOW_S, MAX_WINDOW_S))
        keep = self._state_t >= stamps[-1] - STATE_HISTORY_S
        self._state_t = np.concatenate([self._state_t[keep], stamps])
        self._state_sigma = np.concatenate([self._state_sigma[keep], move.measured_progress(strut_lengths)])

    # -- the watch --------------------------------------------------------------------------------
    def observe(self, stamps, wrenches, newest_state_time: float, next_check_s: float = 0.0) -> GuardTrip | None:
        """Wrench estimates [n, 6] at stamps [n] (s); newest_state_time: the newest joint state's stamp (s,
        the emulator's clock as the node knows it); next_check_s: when the next estimates will be checked
        (s, the node's batch period): the guard trips now if a stop sent then would end above a limit.
        Returns a new trip (with its stop plan) or None."""
        wrenches = np.asarray(wrenches, float)
        if not len(wrenches):
            return None
        self.last_wrench = wrenches[-1]
        self.newest_estimate = max(self.newest_estimate, float(np.max(stamps)))
        move = self.move
        if move is None:
            return None
        stamps = np.asarray(stamps, float)
        force = np.linalg.norm(wrenches[:, :3], axis=1)
        moment = np.linalg.norm(wrenches[:, 3:], axis=1)
        if move.baseline is None:
            move.baseline = (float(force[0]), float(moment[0]))
        if self.trip is not None and move is self._stopping:
            self.peak = (max(self.peak[0], float(force.max())), max(self.peak[1], float(moment.max())))
            stop = self.trip.stop
            if stamps[-1] > (stop.receipt_time + stop.duration if stop else move.end) + WATCH_AFTER_S:
                self.move = None
            return None
        if stamps[-1] > move.end + WATCH_AFTER_S:
            self.move = None
            return None
        if not self._state_t.size:
            return None
        sigma = np.interp(stamps, self._state_t, self._state_sigma)
        move.samples.extend(zip(stamps.tolist(), sigma.tolist(), force.tolist(), moment.tolist()))
        move.samples = [row for row in move.samples if row[0] >= stamps[-1] - FIT_WINDOW_S]
        trip = self.assess(newest_state_time, next_check_s, float(stamps[-1]))
        if trip is not None:
            self.peak = (max(self.peak[0], float(force.max())), max(self.peak[1], float(moment.max())))
        return trip

    def assess(self, newest_state_time: float, next_check_s: float = 0.0, time: float | None = None
               ) -> GuardTrip | None:
        """Trip now if a stop sent ``next_check_s`` s from now would end above a limit, by the load fitted
        against the progress (the latest estimates) extrapolated to that stop's end. Called for every batch of
        estimates and for every batch of joint states: the load is a function of where the struts are, so
        a state that is newer than the newest estimate moves the prediction on (estimates that come late
        do not delay the trip). ``time``: the trip's stamp (default ``newest_state_time``). The next check is
        assumed no sooner than the largest gap between the recent checks (``check_gap``): a node starved of CPU
        checks late, and a guard that looked only ``next_check_s`` ahead tripped too late (30 % over the limit
        at 0.2 s gaps)."""
        self._note_check(newest_state_time)
        move = self.move
        if move is None or move.stopped or move.baseline is None or not move.samples or \
                (self.trip is not None and move is self._stopping):
            return None
        later = self.plan_stop(newest_state_time, max(next_check_s, self.check_gap))
        target = 1.0 if later is None else later.progress
        checks = []
        force_limit, moment_limit = self.limits(move)
        predicted_load = [float("nan"), float("nan")]
        for which, column, limit, base in (("force", 2, force_limit, move.baseline[0]),
                                           ("moment", 3, moment_limit, move.baseline[1])):
            if limit <= 0:
                continue
            now, predicted = _predict(move.samples, column, target)
            predicted_load[column - 2] = float(predicted)
            rising = now > base + 0.01 * limit and predicted > now
            checks.append((which, now, predicted, limit, rising))
        self.predicted = (predicted_load[0], predicted_load[1])
        for which, _now, predicted, limit, rising in checks:
            if rising and predicted > limit:
                values = {c[0]: c for c in checks}
                latest = move.samples[-1]
                f = values.get("force", (None, latest[2], latest[2]))
                m = values.get("moment", (None, latest[3], latest[3]))
                trip = self._trip(move, newest_state_time if time is None else time, newest_state_time,
                                  (float(f[1]), float(m[1])), (float(f[2]), float(m[2])), which, limit=limit)
                return trip
        return None

    def _note_check(self, newest_state_time: float) -> None:
        checks = self._checks
        self._checks = np.append(checks[checks >= newest_state_time - CHECK_MEMORY_S], newest_state_time)

    @property
    def check_gap(self) -> float:
        """The largest gap (s of sim time) between consecutive checks over the last CHECK_MEMORY_S, at most
        MAX_WINDOW_S (a longer silence trips the guard blind instead); 0 before two checks."""
        gaps = np.diff(self._checks)
        return float(min(gaps.max(), MAX_WINDOW_S)) if gaps.size else 0.0

    def check_estimates(self, newest_state_time: float) -> GuardTrip | None:
        """Trip ("estimates") when a move is under way and the newest wrench estimate (or the move's start, if
        none came since) lies more than ``max_estimate_age`` s behind ``newest_state_time`` (s, the emulator's
        clock): the guard cannot see the load, so the struts stop. Returns a new trip or None."""
        if np.isfinite(self.newest_estimate):
            keep = self._lags[:, 0] >= newest_state_time - LAG_MEMORY_S
            self._lags = np.vstack([self._lags[keep], [newest_state_time, newest_state_time - self.newest_estimate]])
        move = self.move
        if move is None or move.stopped or self.max_estimate_age <= 0 or \
                (self.trip is not None and move is self._stopping):
            return None
        if not np.isfinite(self.newest_estimate):  # no estimator has ever answered: unguarded (the node warns)
            return None
        if newest_state_time > move.end:  # the move is over: nothing left to stop
            return None
        seen = max(self.newest_estimate, move.start_time)
        age = newest_state_time - seen
        if age <= self.max_estimate_age:
            return None
        force, moment = float(np.linalg.norm(self.last_wrench[:3])), float(np.linalg.norm(self.last_wrench[3:]))
        detail = (f"no external-wrench estimate for {age:.3f} s of sim time (newest {self.newest_estimate:.3f} s; "
                  f"guard_max_estimate_age_s {self.max_estimate_age:g}): the guard could not see the load")
        self._before_blind = (self.trip, list(self.blocked), self.peak)
        self._fresh_since = None
        return self._trip(move, float(newest_state_time), newest_state_time, (force, moment), (force, moment),
                          "estimates", detail)

    @property
    def estimate_lag(self) -> float:
        """The largest lag (s) of the newest wrench estimate behind the newest state over the last LAG_MEMORY_S
        (as ``check_estimates`` saw it); 0 before any."""
        return float(self._lags[:, 1].max()) if len(self._lags) else 0.0

    def speed_limit(self) -> float:
        """Strut speed (m/s) for the next move such that the struts cover at most ``blind_travel`` m in the
        estimates' lag: a busy machine makes the guard see late, so moves go slower (inf: no limit, when the
        guard is off, no estimator was heard or ``blind_travel`` is 0). Every lag counts in full, also one
        beyond ``max_estimate_age``, so one stall slows the next moves for LAG_MEMORY_S (the runner waits for
        current estimates before its first move). Counting it at most as ``max_estimate_age`` (6 mm/s) relied on
        the blind pause, which comes late when kinematics itself is starved of CPU: beside a hog and the test
        suite, resumed guarded moves at 6 mm/s ran through their stops to 423 N against a 200 N limit.
        """
        if self.blind_travel <= 0 or not np.isfinite(self.newest_estimate) or \
                (self.force_limit <= 0 and self.moment_limit <= 0):
            return float("inf")
        return self.blind_travel / max(self.estimate_lag, 1e-3)

    def blind_stop_over(self, newest_state_time: float) -> bool:
        """An "estimates" trip whose stop is over (the guard watches no move) while the estimates have been
        fresh again (within half of ``max_estimate_age`` of ``newest_state_time``, s) for ``RESUME_FRESH_S``:
        an estimator that keeps falling behind does not get the move going again (CI: resumed into 0.4 s lag)."""
        trip = self.trip
        if trip is None or trip.which != "estimates" or self.move is not None:
            return False
        if newest_state_time - self.newest_estimate > 0.5 * self.max_estimate_age:
            self._fresh_since = None
            return False
        if self._fresh_since is None:
            self._fresh_since = newest_state_time
        return newest_state_time - self._fresh_since >= RESUME_FRESH_S

    def resume_after_blind(self) -> bool:
        """End an "estimates" trip. If the fresh load is within the limits the guard is as it was before it (an
        earlier force trip stays latched) and True is returned: the node sends the interrupted target again.
        If the load the guard could not see has passed a limit meanwhile, the trip becomes a force (moment)
        trip, latched like any other: False, the struts stay where the stop held them."""
        trip = self.trip
        if trip is None or trip.which != "estimates" or self._before_blind is None:
            return False
        force, moment = float(np.linalg.norm(self.last_wrench[:3])), float(np.linalg.norm(self.last_wrench[3:]))
        force_limit, moment_limit = self.limits(self._stopping)
        which = next((name for name, value, limit in (("force", force, force_limit), ("moment", moment, moment_limit))
                      if 0 < limit <= value), None)
        if which is not None:
            self.trip = replace(trip, which=which, force=force, moment=moment, predicted_force=force,
                                predicted_moment=moment, time=self.newest_estimate,
                                limit=force_limit if which == "force" else moment_limit,
                                detail=f"found when estimates returned after a blind stop ({trip.detail})")
            self._before_blind = None
            return False
        self._end_pause()
        return True

    def _end_pause(self) -> None:
        """The guard as it was before the current "estimates" pause; an earlier pause restored with it ends too
        (a pause whose move is gone has nothing to resume, and would otherwise stay latched)."""
        if self._before_blind is not None:
            self.trip, self.blocked, self.peak = self._before_blind
        self._before_blind = None
        if self.trip is not None and self.trip.which == "estimates":
            self.trip, self.blocked, self.peak = None, [], (0.0, 0.0)

    def _trip(self, move: GuardedMove, time: float, newest_state_time: float, load: tuple[float, float],
              predicted: tuple[float, float], which: str, detail: str = "", limit: float = 0.0) -> GuardTrip:
        """Latch a trip of ``move`` at ``time`` (s) with its stop plan; block the move's direction."""
        stop = self.plan_stop(newest_state_time)
        direction = pose_direction(self.robot, move.start_pose, move.goal_pose)
        norm = np.linalg.norm(direction)
        self.trip = GuardTrip(time, load[0], load[1], predicted[0], predicted[1], which, stop, move.goal_pose.copy(),
                              direction / norm if norm > 0 else direction, detail, limit)
        self.blocked.append(self.trip.direction)
        self._stopping = move
        move.stopped = stop is not None  # without a stop the move runs on to its goal
        self.peak = load
        self._stop_retries = 0
        return self.trip

    def plan_stop(self, newest_state_time: float, later_s: float = 0.0, window_s: float | None = None
                  ) -> StopPlan | None:
        """The stop of the current move if commanded now (see the module docstring), or ``later_s`` s from now;
        None if the move would end first (or there is none). ``newest_state_time``: the emulator's time as the
        node knows it (s); the stop is planned for an arrival within ``window_s`` (default: the receipt window)
        after it."""
        move = self.move
        if move is None:
            return None
        scale = move.stroke
        if scale <= 0:
            return None
        newest = newest_state_time + later_s
        t_est = newest + RECEIPT_DELAY_S
        s0, v0, a0 = (float(x[0]) for x in move.progress([t_est]))
        window = self.receipt_window if window_s is None else window_s
        receipt = move.progress(newest + np.linspace(0.0, window, 7))
        lim = self.robot.limits
        acc_max, vel_max = self.deceleration_scale * lim.strut_acceleration_max / scale, lim.strut_velocity_max / scale

        def peaks(duration: float):  # the quintics from every receipt to (final, rest) over ``duration``
            final = s0 + duration * (v0 / 2 + a0 * duration / 12)
            acc, vel = _stop_peaks(receipt, final, duration)
            return final, float(acc.max()), float(vel.max())

        # the shortest duration (to STOP_RESOLUTION_S) whose worst case stays within the limits: grow, then bisect
        low, high = 0.0, max(STOP_DURATIONS_S[0], 1.5 * abs(v0) / acc_max)
        final, acc, vel = peaks(high)
        while (acc > acc_max or vel > vel_max) and high < STOP_DURATIONS_S[-1]:
            low, high = high, high * 1.5
            final, acc, vel = peaks(high)
        while high - low > STOP_RESOLUTION_S and low > 0:
            mid = 0.5 * (low + high)
            f, a, v = peaks(mid)
            if a > acc_max or v > vel_max:
                low = mid
            else:
                high, final, acc = mid, f, a
        if final >= 1.0:
            return None
        return StopPlan(float(high), move.start_lengths + move.delta * final, float(final), t_est, acc * scale)

    def missed_stop(self, newest_state_time: float, refused: bool = False) -> StopPlan | None:
        """A new stop when the commanded one did not take: the emulator ``refused`` it (it arrived later than the
        receipt window allowed) or the measured struts ran past it still following the move; planned from the
        running move for twice the window; None otherwise (struts past it but off the move took the stop late
        and brake along it). At most MAX_STOP_RETRIES times per trip."""
        trip, move = self.trip, self.move
        if trip is None or trip.stop is None or move is None or move is not self._stopping or \
                self._stop_retries >= MAX_STOP_RETRIES:
            return None
        if not refused:
            if not self._state_sigma.size or newest_state_time < trip.stop.receipt_time + self.receipt_window:
                return None
            if self._state_sigma[-1] <= trip.stop.progress + 0.01:
                return None
            if newest_state_time < self.latest_take(move, trip.stop) + ON_MOVE_SETTLE_S or not self.follows_move(move):
                return None  # it may still be taken, or it was (late) and the struts brake along it
        self._stop_retries += 1
        stop = self.plan_stop(newest_state_time, window_s=self.receipt_window * 2**self._stop_retries)
        if stop is not None:
            self.trip = replace(trip, stop=stop)
        return stop

    def latest_take(self, move: GuardedMove, stop: StopPlan) -> float:
        """The latest arrival (s, emulator clock) at which the emulator still takes ``stop`` off ``move``: the
        end of the run of arrivals from ``stop.receipt_time`` (every STOP_RESOLUTION_S) whose quintic keeps
        within strut_acceleration_max and strut_velocity_max (its own check; later ones it refuses)."""
        scale = move.stroke
        lim = self.robot.limits
        arrivals = stop.receipt_time + np.arange(0.0, 2 * MAX_WINDOW_S + stop.duration, STOP_RESOLUTION_S)
        acc, vel = _stop_peaks(move.progress(arrivals), stop.progress, stop.duration)
        refused = (acc * scale > lim.strut_acceleration_max) | (vel * scale > lim.strut_velocity_max)
        first_refused = int(np.argmax(refused)) if refused.any() else arrivals.size
        return float(arrivals[max(first_refused - 1, 0)])

    def follows_move(self, move: GuardedMove) -> bool:
        """Whether the newest measured states still follow ``move`` as planned: progress within
        ON_MOVE_PROGRESS_TOL of the plan at their stamps, and progress rate (slope over ON_MOVE_SPAN_S) within
        ON_MOVE_RATE_TOL of the planned rate. A stop the emulator took, however late, bends them off the plan
        (first in rate); a stop that never took leaves them on it."""
        t, sigma = self._state_t, self._state_sigma
        if not t.size:
            return True
        recent = t >= t[-1] - ON_MOVE_SPAN_S
        planned, rate, _ = move.progress(t[recent])
        if abs(float(sigma[-1] - planned[-1])) > ON_MOVE_PROGRESS_TOL:
            return False
        if np.count_nonzero(recent) < 3:
            return True
        measured_rate = float(np.polyfit(t[recent], sigma[recent], 1)[0])
        planned_rate = float(rate.mean())
        floor = ON_MOVE_RATE_TOL * 1.875 / move.duration  # 1.875 / T: the minimum-jerk move's peak rate
        return abs(measured_rate - planned_rate) <= max(ON_MOVE_RATE_TOL * abs(planned_rate), floor)

    # -- report ---------------------------------------------------------------------------------------
    def status(self) -> GuardStatus:
        """The guard's status (motion.guard_status.GuardStatus): armed (with the limits that watch the current move),
        off (both 0) or the trip with its stop and peaks."""
        force, moment = self.limits()
        trip = self.trip
        if trip is None:
            return GuardStatus("off" if force <= 0 and moment <= 0 else "armed", force, moment, self.message())
        return GuardStatus(
            "tripped", force, moment, self.message(), trip_limit=trip.which, trip_time_s=trip.time,
            trip_force_n=trip.force, trip_moment_nm=trip.moment, predicted_force_n=trip.predicted_force,
            predicted_moment_nm=trip.predicted_moment, peak_force_n=self.peak[0], peak_moment_nm=self.peak[1],
            stop_duration_s=trip.stop.duration if trip.stop else 0.0,
            stop_progress=trip.stop.progress if trip.stop else 1.0,
            tripped_goal=np.array(trip.goal_pose, float), tripped_direction=np.array(trip.direction, float),
            blocked_directions=len(self.blocked))

    def message(self) -> str:
        """One line for the log and /diagnostics: armed with its limits, or the trip, its stop and the latch."""
        trip = self.trip
        if trip is None:
            return (f"armed: guard_force_n {self.force_limit:g} N, guard_moment_nm {self.moment_limit:g} N m "
                    "(0 = off)")
        stop = f"struts stopped over {trip.stop.duration:.2f} s" if trip.stop else "the move ended before a stop"
        return (f"tripped at {trip.time:.3f} s: {trip.which} {self._tripped_value(trip)}; {stop}; holding; goals "
                "further in that direction are refused until kinematics/reset_guard or a new limit")


def _stop_peaks(departures, final: float, duration: float) -> tuple[np.ndarray, np.ndarray]:
    """Largest |acceleration| and |velocity| [n] (progress units: 1/s^2, 1/s) of the quintics from each
    departure state (sigma, sigma_dot, sigma_ddot, each [n]) to (``final``, rest) over ``duration`` (s)."""
    (vp, ap), (vv, av), (va, aa) = _BASES
    p0, v1, a1 = (np.asarray(x, float)[:, None] for x in departures)
    gap = p0 - final
    vel = gap * vp / duration + v1 * vv + a1 * va * duration
    acc = gap * ap / duration**2 + v1 * av / duration + a1 * aa
    return np.abs(acc).max(axis=1), np.abs(vel).max(axis=1)


def _predict(samples, column: int, target_progress: float) -> tuple[float, float]:
    """(latest value, predicted value at ``target_progress``) of column 2 (force) or 3 (moment) of the
    (t, sigma, |F|, |M|) samples: quadratic least squares in sigma around the latest progress (linear with
    few samples or little spread; the latest value when the progress does not change), extrapolated with the
    fit's slope F' and curvature F'' at the latest progress as an exponential while the load rises
    (F + F' (exp(r d) - 1) / r, r = F''/F', d the progress ahead): soft tissue stiffens with distraction, and
    a quadratic under-predicts an exponential the further it looks ahead."""
    rows = np.asarray(samples, float)
    now = float(rows[-1, column])
    if len(rows) < MIN_FIT_SAMPLES:
        return now, now
    x = rows[:, 1] - rows[-1, 1]
    span = float(np.ptp(x))
    ahead = max(target_progress - rows[-1, 1], 0.0)
    if span < 1e-6:
        return now, now
    degree = 2 if len(rows) >= 2 * MIN_FIT_SAMPLES and span > 0.2 * ahead else 1
    coef = np.polyfit(x / span, rows[:, column], degree)
    # a: how far ahead, in spans of the fitted progress; capped: a trend seen over a sliver of progress (a fast
    # move's first estimates, model error of a few N) extrapolated 100 spans ahead predicted 1.5 kN (CI)
    a = min(ahead / span, MAX_EXTRAPOLATION)
    slope, curvature = float(coef[-2]), (2.0 * float(coef[0]) if degree == 2 else 0.0)
    polynomial = float(np.polyval(coef, a) - np.polyval(coef, 0.0))
    if slope <= 0 or abs(curvature) < 1e-9 * slope:  # not rising here, or straight: the polynomial itself
        return now, now + polynomial
    # rising: continue with the local growth rate r = F''/F' (exponential stiffening keeps it): F' (e^{ra} - 1)/r,
    # never below the quadratic (its Taylor series has the quadratic's terms and more of the same sign). r a is
    # capped: on a load that is mostly noise (no tissue) r is noise over noise, and e^{ra} predicted 600 N from 2 N
    rate = curvature / slope
    return now, now + max(polynomial, slope * float(np.expm1(min(rate * a, MAX_GROWTH_EXPONENT))) / rate)

__all__ = [
    "ForceGuard",
    "GuardTrip",
    "GuardedMove",
    "StopPlan",
    "pose_direction",
]
