"""The force guard of reduction moves (pure numpy): watch the external-wrench estimate during a move, stop the
struts smoothly before the load passes a limit, hold, and refuse further targets in that direction until the
operator resets the guard or changes the limit. The kinematics node only wires it to topics.

Its parts, one idea each: the move and its progress sigma (``guarded_move``), the load fitted against the
progress and extrapolated (``load_prediction``), the stop that keeps the struts within their limits
(``stop_planning``), the freshness of the estimates (``estimate_watch``). This module is the state machine:

    armed --begin_move--> watching a move --the move or its stop ends (+ WATCH_AFTER_S)--> armed
      ^                     |                        |
      | reset or            | predicted load         | newest estimate older than max_estimate_age
      | new limits          v over a limit           v
      +------------------ tripped <--------------- blind pause (an "estimates" trip, with its stop)
                          (latched: the move's     load over a limit       | estimates fresh for
                           direction is refused)   when estimates return   | RESUME_FRESH_S after the stop
                                                                           v
                                                   the state before the pause; the node sends the
                                                   interrupted target again
    (both limits 0: "off", no load is judged)

Trip. For every batch of wrench estimates and of joint states during a move the guard predicts the load at the
end of the stop it would command now. A state newer than the newest estimate moves that progress on, so
estimates that lag do not delay the trip; the stop is assumed sent at the next check, no sooner than the largest
gap between the recent checks (``CheckGaps``). It trips when the predicted force (moment) exceeds ``force_limit``
(``moment_limit``) and the load has risen since the move's start (``judge_load``). A limit of 0 is off.

Missed stops. If the emulator refuses the stop (it arrived later than the receipt window allowed) or the
measured struts run past it while still following the move (the stop never took), ``missed_stop`` plans another
over a doubled window; struts past it that have left the move took it late: its quintic overshoots the end
within the limits and returns, and they get no new stop (one planned from the move would drive them on). The
receipt window widens to twice the command delays measured on the moves (their starts calibrated from the
measured lengths).

Blind. While a move is under way, a newest wrench estimate older than ``max_estimate_age`` (s of sim time)
behind the newest joint state trips the guard too, with the same stop: no estimate, no motion. Until a first
estimate has arrived at all (no estimator running) moves are unguarded; the node warns. Moves are slowed by the
estimates' lag (``speed_limit``).

Latch. A trip blocks the direction of the move (pose space, rotations scaled by the robot's characteristic
length): a target with a component along it is refused with the reason; others (back, sideways) are watched
like any move (a second trip blocks its direction too). ``reset`` or new limits clear the latch.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import GuardBlockedError
from ..robot import Robot
from .estimate_watch import BLIND_TRAVEL_M, MAX_ESTIMATE_AGE_S, CheckGaps, EstimateWatch
from .guard_status import GuardStatus, guard_message, guard_status, trip_figures
from .guarded_move import GuardedMove, GuardTrip, StopPlan, pose_direction
from .load_prediction import FIT_WINDOW_S, judge_load
from .stop_planning import MAX_WINDOW_S, RECEIPT_DELAY_S, RECEIPT_WINDOW_S, latest_take, plan_stop

STATE_HISTORY_S = 2.0  # measured progress kept for the estimates (which lag the states)
MAX_STOP_RETRIES = 3
DIRECTION_TOLERANCE_M = 1e-6  # a target further along a tripped direction than this (m, pose space) is refused
WATCH_AFTER_S = 0.3  # the guard keeps watching (and recording peaks) this long after a move or stop ends
ON_MOVE_SETTLE_S = 0.1  # struts judged on the move only this long (s) after the latest a stop could be taken


class ForceGuard:
    """See the module docstring. Limits in N and N m (0 = off); deceleration_scale: the fraction of
    strut_acceleration_max a stop may use; max_estimate_age: s of sim time a move goes on without a fresh
    wrench estimate (0 = never stop for that); blind_travel: m the struts may cover in the estimates' lag."""

    _before_blind: tuple[GuardTrip | None, list[np.ndarray], tuple[float, float]] | None
    _delays: list[float]

    def __init__(self, robot: Robot, force_limit: float, moment_limit: float, deceleration_scale: float = 0.8,
                 max_estimate_age: float = MAX_ESTIMATE_AGE_S, blind_travel: float = BLIND_TRAVEL_M):
        self.robot = robot
        self.estimates = EstimateWatch(max_estimate_age, blind_travel)
        self._before_blind = None  # (trip, blocked, peak) before an "estimates" trip: restored when they return
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
        self.checks = CheckGaps()  # when assess ran: the next check comes no sooner than the largest recent gap
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
        self.move, self._stopping = None, None
        self.estimates.reset_freshness()
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
        None (``GuardedMove.under_way``). A target sent while the struts move would be planned from rest: the
        emulator refuses it and runs on, while the guard would watch the refused move instead; and a train of
        targets each arriving before the last one's start would otherwise all be taken."""
        return None if self.move is None else self.move.under_way(now)

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
                f"force guard tripped at {trip.time:.3f} s ({trip.which} {trip_figures(trip)}): a goal "
                f"{along * 1e3:.3f} mm further along the stopped move's direction is refused until "
                "kinematics/reset_guard is called or guard_force_n / guard_moment_nm is changed",
                limit_name="force_guard", value=along, limit=0.0)

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

    # -- the watch --------------------------------------------------------------------------------------
    def observe(self, stamps, wrenches, newest_state_time: float, next_check_s: float = 0.0) -> GuardTrip | None:
        """Wrench estimates [n, 6] at stamps [n] (s); newest_state_time: the newest joint state's stamp (s,
        the emulator's clock as the node knows it); next_check_s: when the next estimates will be checked
        (s, the node's batch period): the guard trips now if a stop sent then would end above a limit.
        Returns a new trip (with its stop plan) or None."""
        wrenches = np.asarray(wrenches, float)
        if not len(wrenches):
            return None
        self.last_wrench = wrenches[-1]
        self.estimates.arrived(stamps)
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
        assumed no sooner than the largest gap between the recent checks (``CheckGaps``): a node starved of CPU
        checks late, and a guard that looked only ``next_check_s`` ahead would trip too late."""
        self.checks.checked(newest_state_time)
        move = self.move
        if move is None or move.stopped or move.baseline is None or not move.samples or \
                (self.trip is not None and move is self._stopping):
            return None
        later = self.plan_stop(newest_state_time, max(next_check_s, self.checks.gap))
        verdict = judge_load(move.samples, move.baseline, self.limits(move), 1.0 if later is None else later.progress)
        self.predicted = verdict.predicted
        if verdict.which is None:
            return None
        return self._trip(move, newest_state_time if time is None else time, newest_state_time, verdict.load,
                          verdict.predicted_at_trip, verdict.which, limit=verdict.limit)

    # -- blind: the estimates late ------------------------------------------------------------------------
    def check_estimates(self, newest_state_time: float) -> GuardTrip | None:
        """Trip ("estimates") when a move is under way and the newest wrench estimate (or the move's start, if
        none came since) lies more than ``max_estimate_age`` s behind ``newest_state_time`` (s, the emulator's
        clock): the guard cannot see the load, so the struts stop. Returns a new trip or None."""
        watch = self.estimates
        watch.checked(newest_state_time)
        move = self.move
        if move is None or move.stopped or watch.max_estimate_age <= 0 or \
                (self.trip is not None and move is self._stopping):
            return None
        if not watch.heard:  # no estimator has ever answered: unguarded (the node warns)
            return None
        if newest_state_time > move.end:  # the move is over: nothing left to stop
            return None
        age = watch.age(newest_state_time, move.start_time)
        if age <= watch.max_estimate_age:
            return None
        force, moment = float(np.linalg.norm(self.last_wrench[:3])), float(np.linalg.norm(self.last_wrench[3:]))
        detail = (f"no external-wrench estimate for {age:.3f} s of sim time (newest {watch.newest:.3f} s; "
                  f"guard_max_estimate_age_s {watch.max_estimate_age:g}): the guard could not see the load")
        self._before_blind = (self.trip, list(self.blocked), self.peak)
        watch.reset_freshness()
        return self._trip(move, float(newest_state_time), newest_state_time, (force, moment), (force, moment),
                          "estimates", detail)

    @property
    def estimate_lag(self) -> float:
        """The largest lag (s) of the newest wrench estimate behind the newest state over the last LAG_MEMORY_S
        (as ``check_estimates`` saw it); 0 before any."""
        return self.estimates.lag

    def speed_limit(self) -> float:
        """Strut speed (m/s) for the next move (``EstimateWatch.speed_limit``): a busy machine makes the guard see
        late, so moves go slower; inf when the guard is off."""
        if self.force_limit <= 0 and self.moment_limit <= 0:
            return float("inf")
        return self.estimates.speed_limit()

    def blind_stop_over(self, newest_state_time: float) -> bool:
        """An "estimates" trip whose stop is over (the guard watches no move) while the estimates have kept up
        again (``EstimateWatch.kept_up``)."""
        trip = self.trip
        if trip is None or trip.which != "estimates" or self.move is not None:
            return False
        return self.estimates.kept_up(newest_state_time)

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
                                predicted_moment=moment, time=self.estimates.newest,
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

    # -- trips and stops ------------------------------------------------------------------------------
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
        """The stop of the current move if commanded now, or ``later_s`` s from now (``stop_planning.plan_stop``);
        None if the move would end first (or there is none). ``newest_state_time``: the emulator's time as the
        node knows it (s); the stop is planned for an arrival within ``window_s`` (default: the receipt window)."""
        if self.move is None:
            return None
        window = self.receipt_window if window_s is None else window_s
        return plan_stop(self.move, self.robot.limits, self.deceleration_scale, newest_state_time, window, later_s)

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
        """The latest arrival (s, emulator clock) at which the emulator still takes ``stop`` off ``move``."""
        return latest_take(move, stop, self.robot.limits)

    def follows_move(self, move: GuardedMove) -> bool:
        """Whether the newest measured states still follow ``move`` as planned (``GuardedMove.followed_by``)."""
        return move.followed_by(self._state_t, self._state_sigma)

    # -- report ---------------------------------------------------------------------------------------
    def status(self) -> GuardStatus:
        """The guard's status: armed (with the limits that watch the current move), off (both 0) or the trip."""
        force, moment = self.limits()
        return guard_status(self.trip, force, moment, self.message(), self.peak, len(self.blocked))

    def message(self) -> str:
        """One line for the log and /diagnostics: armed with its limits, or the trip, its stop and the latch."""
        return guard_message(self.trip, self.force_limit, self.moment_limit)
