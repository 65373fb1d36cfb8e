"""The kinematics node's move goals from acceptance to their end (pure): which goal runs, what was sent for it,
the target to send again after a blind pause, a goal's wait for struts that still move on their own, and what
each event means for the goal -- a cancel, a trip of the force guard, the robot's answer to a leg trajectory, a
stop the robot made itself. Events go in and what the node must do comes out (the guard supervisor's actions,
or small records to log); motion.move_goal.MoveWatch decides when a goal ends and how.

Times are s of the robot's clock (``wall_now`` monotonic s); lengths m; poses (6,) [x, y, z, roll, pitch, yaw]
in m and rad in the base frame; loads N and N m.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import RefusedError, StewartError
from ..kinematics import check_pose
from ..robot import Robot
from .guard_status import GUARD_STATES
from .guard_supervisor import Action, GuardSupervisor, PublishStatus, SendStop
from .guarded_move import GuardTrip, StopPlan
from .move_goal import MoveEnd, MoveRequest, MoveWatch, move_request, pose_errors

REST_WAIT_S = 60.0  # a goal waits this long (robot's clock) for struts moving on their own to stop
REST_WAIT_WALL_S = 120.0  # ... and at most this long on the wall clock (no states: the robot is gone)
ROBOT_REFUSALS = ("ESTOP_LATCHED", "ROBOT_INACTIVE")  # the robot's codes a refused move ends with (else ROBOT_REFUSED)


@dataclass
class RunningGoal:
    """A move goal under way: its action handle (opaque here: what a cancel names), request and watch, when it
    began (s), the peak load of the estimates since (N, N m) and, once over, its end and duration (s)."""

    handle: Any
    request: MoveRequest
    watch: MoveWatch
    start: float
    peak_force: float = 0.0
    peak_moment: float = 0.0
    end: MoveEnd | None = None
    duration: float = 0.0

    def summary(self, pose) -> MoveSummary:
        """The goal's result once over, with the residual error of ``pose`` (the newest estimate; None: none)."""
        if self.end is None:
            raise ValueError("a goal's summary is known once it has ended")
        end = self.end
        errors = (0.0, 0.0) if pose is None else pose_errors(pose, self.request.target)
        return MoveSummary(end.outcome, end.message, pose, *errors, self.peak_force, self.peak_moment, self.duration)


@dataclass(frozen=True)
class MoveSummary:
    """What a goal's result reports: the outcome name and message, the final pose estimate (None: none yet) and
    its distance (m) and rotation angle (rad) to the target, the peak load (N, N m) and the duration (s)."""

    outcome: str
    message: str
    final_pose: np.ndarray | None = None
    position_error: float = 0.0
    angle_error: float = 0.0
    peak_force: float = 0.0
    peak_moment: float = 0.0
    duration: float = 0.0


@dataclass(frozen=True)
class MoveFeedback:
    """A running goal's feedback: progress (0 start .. 1 target), time left (s), the pose estimate, the newest
    load estimate (6,) [force N, torque N m], the load the guard predicts at a stop's end (N, N m) and the
    guard's state (index of GUARD_STATES)."""

    progress: float
    time_remaining: float
    pose: np.ndarray
    load: np.ndarray
    predicted_force: float
    predicted_moment: float
    guard_state: int


@dataclass(frozen=True)
class SentStop:
    """The last stop sent: where the struts come to rest (6,) (m), on whose behalf ("guard" or "cancel") and
    how many refused stops came before it."""

    lengths: np.ndarray
    by: str
    attempt: int


@dataclass(frozen=True)
class RestWait:
    """A goal (``handle``) waiting for the struts to stop, until the deadlines (s, robot's and wall clock)."""

    handle: Any
    sim_deadline: float
    wall_deadline: float

    def settled(self, at_rest: bool, cancel_requested: bool, ending: bool, sim_now: float, wall_now: float
                ) -> bool | None:
        """True once the struts are at rest or the goal is cancelled (it goes on to its next check), False past
        a deadline or when the node is ``ending``, None while it waits."""
        if at_rest or cancel_requested:
            return True
        if ending or sim_now > self.sim_deadline or wall_now > self.wall_deadline:
            return False
        return None


@dataclass(frozen=True)
class Cancelled:
    """The running goal is cancelled: send ``stop`` (None: the move ends before a stop could)."""

    stop: StopPlan | None


@dataclass(frozen=True)
class RobotStop:
    """The robot stopped a move itself: why, and the target abandoned (rounded to 10 um; None: none)."""

    why: str
    target: list | None


def rest_refusal(speed: float | None) -> RefusedError:
    """The refusal of a goal whose struts did not stop within REST_WAIT_S (``speed``: the fastest strut's
    drift, m/s; None: unknown)."""
    drift = "" if speed is None else f" (the fastest drifts at {speed * 1e3:.3f} mm/s)"
    return RefusedError("STRUTS_NOT_AT_REST", f"the struts did not come to rest within {REST_WAIT_S:g} s{drift}: a "
                        "move is planned from rest; send it again once the robot has stopped")


class GoalKeeper:
    """One goal at a time for ``robot``, its moves watched by the guard of ``supervisor``."""

    def __init__(self, robot: Robot, supervisor: GuardSupervisor):
        self.robot, self.supervisor, self.guard = robot, supervisor, supervisor.guard
        self.goal: RunningGoal | None = None
        self.rest_wait: RestWait | None = None
        self.last_target: MoveRequest | None = None  # the goal's request, sent again after a blind pause
        self.sent_move: np.ndarray | None = None  # the final lengths of the last move sent (its key)
        self.sent_stop: SentStop | None = None
        self.robot_stop_seen: tuple | None = None  # (ramp start, cause, fault) of the last robot stop acted on

    # -- a new goal -----------------------------------------------------------------------------------
    def check_free(self) -> None:
        """RefusedError BUSY while another goal runs or waits for the struts."""
        if self.goal is not None or self.rest_wait is not None:
            raise RefusedError("BUSY", "another move goal is running: cancel it or wait for its result")

    def request(self, target, speed_scale: float, force_limit: float, moment_limit: float,
                default_speed_scale: float) -> MoveRequest:
        """A goal's checked request (motion.move_goal.move_request under the guard's limits; the target
        reachable). Raises the typed refusal."""
        request = move_request(target, speed_scale, force_limit, moment_limit, default_speed_scale,
                               self.guard.force_limit, self.guard.moment_limit)
        check_pose(self.robot, target)
        return request

    def wait_for_rest(self, handle, sim_now: float, wall_now: float) -> RestWait:
        """A goal starts waiting for the struts to stop."""
        self.rest_wait = RestWait(handle, sim_now + REST_WAIT_S, wall_now + REST_WAIT_WALL_S)
        return self.rest_wait

    def rest_wait_over(self) -> None:
        """The goal waits no more (it goes on, or was refused)."""
        self.rest_wait = None

    def begin(self, handle, request: MoveRequest, pose, now: float, tolerances: tuple,
              send_move: Callable[[MoveRequest], float]) -> RunningGoal:
        """Follow a goal from ``pose`` once ``send_move(request)`` has sent its move (returning its estimated end,
        s); ``tolerances``: MoveWatch's (position m, angle rad, goal time s, pause timeout s). Raises
        RefusedError NOT_READY without a pose estimate, or the refusal of the move."""
        if pose is None:
            raise RefusedError("NOT_READY", "no legs/joint_states received yet (is the hardware emulator running?)")
        watch = MoveWatch(pose, request.target, *tolerances)
        watch.moving(send_move(request))
        self.goal = RunningGoal(handle, request, watch, now)
        return self.goal

    # -- what was sent --------------------------------------------------------------------------------
    def move_sent(self, request: MoveRequest, final_lengths) -> None:
        """A move to ``request``'s target was sent, ending at ``final_lengths`` (6,)."""
        self.sent_move = np.array(final_lengths, float)
        self.last_target = request

    def stop_sent(self, lengths, by: str, attempt: int = 0) -> None:
        """A stop at ``lengths`` (6,) was sent on behalf of ``by``, after ``attempt`` refused ones."""
        self.sent_stop = SentStop(np.array(lengths, float), by, attempt)

    # -- events ---------------------------------------------------------------------------------------
    def observe_load(self, wrenches) -> None:
        """Wrench estimates [n, 6] arrived: the running goal's peak load."""
        if self.goal is not None and len(wrenches):
            wrenches = np.asarray(wrenches, float)
            self.goal.peak_force = max(self.goal.peak_force, float(np.linalg.norm(wrenches[:, :3], axis=1).max()))
            self.goal.peak_moment = max(self.goal.peak_moment, float(np.linalg.norm(wrenches[:, 3:], axis=1).max()))

    def cancel(self, handle, now: float, states_known: bool) -> Cancelled | None:
        """A client cancels the goal ``handle``: None unless it is the running one (a goal still waiting for the
        struts ends at its next check). The goal stops along its path within the guard's deceleration (once
        ``states_known``; none if the move ends first), ends CANCELED at rest, and is not resumed."""
        goal = self.goal
        if goal is None or goal.handle is not handle:
            return None
        self.last_target = None
        stop = self.guard.cancel(now) if states_known else None
        if stop is not None:
            goal.watch.stopping("CANCELED", stop.receipt_time + stop.duration, now,
                                f"cancelled: the struts stopped over {stop.duration:.2f} s")
        else:
            end = goal.watch.until if goal.watch.phase == "moving" else now
            goal.watch.stopping("CANCELED", end, now, "cancelled: the move ended before a stop could")
        return Cancelled(stop)

    def tripped(self, trip: GuardTrip, held: bool, now: float, message: str) -> None:
        """The guard tripped: a force or moment trip ends the goal GUARD_STOPPED once the struts are at rest (at
        the stop's end; now when an earlier stop ``held`` them already), a trip for late estimates pauses it."""
        if self.goal is None:
            return
        move = self.guard.move
        end = trip.stop.receipt_time + trip.stop.duration if trip.stop is not None else \
            (move.end if move is not None else now)
        why = "PAUSED" if trip.which == "estimates" else "GUARD_STOPPED"
        self.goal.watch.stopping(why, now if held else end, now, message)

    def resumed(self, end_time: float) -> None:
        """The paused move was sent again, ending at ``end_time``."""
        if self.goal is not None:
            self.goal.watch.moving(end_time)

    def resume_failed(self, error: StewartError) -> None:
        """The paused move could not be sent again: the goal ends with why."""
        self.last_target = None
        if self.goal is not None:
            self.goal.watch.end(error.outcome, f"the move could not resume after a pause: {error}")

    def on_trajectory_answer(self, final_lengths, accepted: bool, end_time: float, outcome: str, message: str,
                             now: float) -> list[Action]:
        """The robot's answer to a leg trajectory, matched to what was sent by its final lengths (6,): a refused
        stop is planned again over a wider window (the supervisor's SendStop; a cancel's keeps the goal ending
        CANCELED); a taken move tells the goal its end (``end_time``, NaN: unknown); a refused move ends the goal
        with the robot's ``outcome`` when it cannot move now (ROBOT_REFUSALS), else ROBOT_REFUSED, and the
        guard drops it (PublishStatus)."""
        stop, goal = self.sent_stop, self.goal
        if stop is not None and np.array_equal(final_lengths, stop.lengths):
            if accepted:
                return []
            actions = self.supervisor.on_stop_refused(stop.by, stop.attempt, now, message)
            for retry in actions:
                if isinstance(retry, SendStop) and goal is not None and stop.by == "cancel":
                    goal.watch.stopping("CANCELED", retry.stop.receipt_time + retry.stop.duration, now,
                                        "cancelled: the struts stopped")
            return actions
        if self.sent_move is None or not np.array_equal(final_lengths, self.sent_move) or goal is None:
            return []
        if accepted:
            if goal.watch.phase == "moving" and np.isfinite(end_time):
                goal.watch.moving(end_time)
            return []
        self.guard.robot_stopped()
        self.last_target = None
        name = outcome if outcome in ROBOT_REFUSALS else "ROBOT_REFUSED"
        goal.watch.end(name, f"the robot refused the move: {message}")
        return [PublishStatus()]

    def on_robot_status(self, fault: str, ramp_start: float | None, ramp_cause: str | None, ramp_reason: str,
                        strut_stop_causes) -> RobotStop | None:
        """The robot's status: a stop of the struts it made itself (a ramp whose cause is in
        ``strut_stop_causes``, or a latched physics ``fault``) ends the goal and the guard's move, once per stop;
        the target is not sent again. A RobotStop to report when a move or target was dropped."""
        stopped = bool(fault) or (ramp_start is not None and ramp_cause in strut_stop_causes)
        key = (ramp_start, ramp_cause, fault)
        if not stopped or key == self.robot_stop_seen:
            return None
        self.robot_stop_seen = key
        dropped = self.guard.robot_stopped()
        request, self.last_target = self.last_target, None
        why = f"physics fault: {fault}" if fault else ramp_reason
        if self.goal is not None:
            name = "PHYSICS_FAULT" if fault else "EMERGENCY_STOPPED" if ramp_cause == "emergency_stop" \
                else "STOPPED_EARLY"
            self.goal.watch.end(name, f"the robot stopped the move itself ({why})")
        if not dropped and request is None:
            return None
        return RobotStop(why, None if request is None else np.round(request.target, 5).tolist())

    # -- following the goal ---------------------------------------------------------------------------
    def feedback(self, now: float, pose) -> MoveFeedback:
        """The running goal's feedback at ``now`` with the estimate ``pose`` (ValueError without a goal)."""
        if self.goal is None:
            raise ValueError("feedback needs a running goal")
        watch, guard = self.goal.watch, self.guard
        return MoveFeedback(watch.progress(pose), watch.time_remaining(now), np.array(pose, float),
                            guard.last_wrench.copy(), *guard.predicted, GUARD_STATES.index(guard.status().state))

    def follow(self, now: float, pose) -> RunningGoal | None:
        """The running goal if it has ended by ``now`` with the estimate ``pose`` (it is over then), else None."""
        if self.goal is None:
            return None
        end = self.goal.watch.update(now, pose)
        return None if end is None else self.finish(end, now)

    def finish(self, end: MoveEnd, now: float) -> RunningGoal | None:
        """End the running goal with ``end`` at ``now`` and forget it (a goal that did not succeed is not
        resumed); returns it, None if there was none."""
        goal, self.goal = self.goal, None
        if goal is None:
            return None
        if end.outcome != "SUCCEEDED":
            self.last_target = None
        goal.end, goal.duration = end, now - goal.start
        return goal
