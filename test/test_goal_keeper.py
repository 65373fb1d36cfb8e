"""The kinematics node's move goals without ROS (motion.goal_keeper): a goal driven on a stepped robot clock
through what the node hears -- its move sent, the robot's answers, the load estimates, a cancel, the guard's
trips, the robot's own stops, a wait for struts that still move -- and what comes out: the goal's end and
outcome, its feedback and result values (against hand-computed loads and errors), the stops to send again."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration import inverse_kinematics
from stewart_vibration.emulation.vibration_status import STRUT_STOP_CAUSES
from stewart_vibration.errors import RefusedError, StewartError, StrokeLimitError
from stewart_vibration.motion.force_guard import ForceGuard
from stewart_vibration.motion.goal_keeper import (
    REST_WAIT_S,
    REST_WAIT_WALL_S,
    Cancelled,
    GoalKeeper,
    MoveSummary,
    RobotStop,
    rest_refusal,
)
from stewart_vibration.motion.guard_supervisor import GuardSupervisor, PublishStatus, SendStop, Tripped
from stewart_vibration.motion.move_goal import SETTLE_S, MoveEnd
from stewart_vibration.motion.profiles import minimum_jerk

TOLERANCES = (1e-4, 1e-3, 2.0, 30.0)  # position m, angle rad, goal time s, pause timeout s
MOVE_S = 1.0
LIFT = np.array([0.0, 0.0, 0.01, 0.0, 0.0, 0.0])


class Goal:
    """A keeper, its guard and one goal of a 10 mm lift from home, its move sent at 0 s and run for MOVE_S."""

    def __init__(self, robot, force_limit: float = 200.0):
        self.robot = robot
        self.guard = ForceGuard(robot, force_limit, 15.0)
        self.supervisor = GuardSupervisor(self.guard, 0.02)
        self.keeper = GoalKeeper(robot, self.supervisor)
        self.target = robot.home_pose + LIFT
        self.l0, self.l1 = inverse_kinematics(robot, robot.home_pose), inverse_kinematics(robot, self.target)
        self.handle = object()
        self.request = self.keeper.request(self.target, 0.0, 0.0, 0.0, 0.5)
        self.goal = self.keeper.begin(self.handle, self.request, robot.home_pose, 0.0, TOLERANCES, self.send)

    def send(self, request) -> float:
        """What the node does: the move sent (its final lengths kept) and watched by the guard; its end (s)."""
        self.keeper.move_sent(request, self.l1)
        self.guard.begin_move(0.0, MOVE_S, self.l0, self.l1, self.robot.home_pose, request.target)
        return MOVE_S

    def states(self, until: float) -> None:
        """The struts on the plan up to ``until`` (s)."""
        times = np.arange(0.0, until, 0.002)
        self.supervisor.states_read(times, minimum_jerk(self.l0, self.l1, MOVE_S, times)[0])


def test_a_goal_is_followed_from_its_move_to_success_with_its_feedback_and_result(robot):
    g = Goal(robot)
    keeper = g.keeper
    assert (g.request.speed_scale, g.request.force_limit, g.request.moment_limit) == (0.5, 200.0, 15.0)
    with pytest.raises(RefusedError) as busy:
        keeper.check_free()
    assert busy.value.outcome == "BUSY"
    feedback = keeper.feedback(0.25, robot.home_pose)
    assert (feedback.progress, feedback.time_remaining, feedback.guard_state) == (0.0, 0.75, 0)  # armed
    assert np.array_equal(feedback.load, np.zeros(6)) and np.isnan(feedback.predicted_force)
    keeper.observe_load([[3.0, 4.0, 0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 1.0, 2.0, 2.0]])
    keeper.observe_load([[1.0, 0.0, 0.0, 0.0, 1.0, 0.0]])  # smaller: the peaks stay
    assert (g.goal.peak_force, g.goal.peak_moment) == (5.0, 3.0)
    # the robot took the move and says when it ends: the goal waits for that end
    assert keeper.on_trajectory_answer(g.l1, True, 1.2, "SUCCEEDED", "", 0.1) == []
    assert keeper.feedback(0.2, robot.home_pose).time_remaining == pytest.approx(1.0)
    arrived = g.target + [3e-6, 4e-6, 0.0, 0.0, 0.0, 0.0]
    assert keeper.follow(1.2 + SETTLE_S - 1e-3, arrived) is None
    ended = keeper.follow(1.2 + SETTLE_S, arrived)
    assert ended is g.goal and ended.end.outcome == "SUCCEEDED" and keeper.goal is None
    assert ended.duration == pytest.approx(1.2 + SETTLE_S)
    assert keeper.last_target is g.request  # only an end short of the target drops it
    summary = ended.summary(arrived)
    assert summary == MoveSummary("SUCCEEDED", ended.end.message, arrived, pytest.approx(5e-6), 0.0, 5.0, 3.0,
                                  pytest.approx(1.2 + SETTLE_S))
    keeper.check_free()


def test_a_goals_request_and_its_start_are_checked(robot):
    keeper = GoalKeeper(robot, GuardSupervisor(ForceGuard(robot, 200.0, 0.0), 0.02))
    with pytest.raises(StrokeLimitError):
        keeper.request(robot.home_pose + [0, 0, 0.2, 0, 0, 0], 0.0, 0.0, 0.0, 0.5)
    lower = keeper.request(robot.home_pose, 0.3, 50.0, 2.0, 0.5)  # the guard's moment off: a goal may set one
    assert (lower.speed_scale, lower.force_limit, lower.moment_limit) == (0.3, 50.0, 2.0)
    sent = []
    with pytest.raises(RefusedError) as not_ready:
        keeper.begin(object(), lower, None, 0.0, TOLERANCES, sent.append)
    assert not_ready.value.outcome == "NOT_READY" and sent == [] and keeper.goal is None


def test_a_refused_move_ends_the_goal_with_the_robots_code_and_the_guard_drops_it(robot):
    g = Goal(robot)
    assert g.keeper.on_trajectory_answer(g.l0, False, np.nan, "LIMIT_EXCEEDED", "not this one", 0.1) == []
    assert g.keeper.on_trajectory_answer(g.l1, False, np.nan, "ESTOP_LATCHED", "e-stop latched", 0.1) == \
        [PublishStatus()]
    assert g.guard.move is None and g.keeper.last_target is None
    ended = g.keeper.follow(0.1, robot.home_pose)
    assert ended.end == MoveEnd("ESTOP_LATCHED", "the robot refused the move: e-stop latched")
    other = Goal(robot)
    other.keeper.on_trajectory_answer(other.l1, False, np.nan, "LIMIT_EXCEEDED", "too fast", 0.1)
    assert other.keeper.follow(0.1, robot.home_pose).end.outcome == "ROBOT_REFUSED"


def test_a_cancel_stops_along_the_path_and_a_refused_stop_is_planned_again(robot):
    g = Goal(robot)
    g.states(0.4)
    assert g.keeper.cancel(object(), 0.4, True) is None  # another goal's handle: nothing happens
    cancelled = g.keeper.cancel(g.handle, 0.4, True)
    stop = cancelled.stop
    assert stop is not None and 0.0 < stop.progress < 1.0 and g.keeper.last_target is None
    assert (g.goal.watch.phase, g.goal.watch.until) == ("stopping", stop.receipt_time + stop.duration)
    g.keeper.stop_sent(stop.lengths, "cancel")
    assert g.keeper.on_trajectory_answer(stop.lengths, True, 0.5, "SUCCEEDED", "", 0.41) == []
    actions = g.keeper.on_trajectory_answer(stop.lengths, False, np.nan, "LIMIT_EXCEEDED", "arrived late", 0.42)
    (retry,) = actions
    assert isinstance(retry, SendStop) and (retry.by, retry.attempt) == ("cancel", 1)
    assert "arrived late" in retry.why and retry.stop.duration >= stop.duration - 1e-9
    end = retry.stop.receipt_time + retry.stop.duration
    assert g.goal.watch.until == end
    held = g.robot.home_pose + LIFT * retry.stop.progress
    assert g.keeper.follow(end + SETTLE_S - 1e-3, held) is None
    ended = g.keeper.follow(end + SETTLE_S, held)
    assert ended.end.outcome == "CANCELED" and ended.end.message.startswith("cancelled: the struts stopped; at rest")
    # before any state there is no stop to send: the goal ends CANCELED at its move's planned end
    early = Goal(robot)
    assert early.keeper.cancel(early.handle, 0.0, False) == Cancelled(None)
    assert early.goal.watch.until == MOVE_S and early.keeper.follow(MOVE_S + SETTLE_S, g.target).end.outcome == \
        "CANCELED"


def test_a_force_trip_stops_the_goal_a_held_one_at_once_and_a_blind_pause_waits(robot):
    g = Goal(robot)
    g.states(0.4)
    stamps = np.arange(0.25, 0.4, 0.002)
    wrenches = np.zeros((stamps.size, 6))
    wrenches[:, 2] = 2000.0 * (stamps - 0.25)  # rising through the 200 N limit
    actions = g.supervisor.on_wrenches(stamps, wrenches, 0.4, 0.4, True)
    trip = next(a.trip for a in actions if isinstance(a, Tripped))
    assert trip.which == "force" and trip.stop is not None
    g.keeper.tripped(trip, False, 0.4, "force guard tripped")
    end = trip.stop.receipt_time + trip.stop.duration
    assert (g.goal.watch.why, g.goal.watch.until) == ("GUARD_STOPPED", end)
    g.keeper.cancel(g.handle, 0.41, True)  # a cancel while the guard stops: still the guard's outcome
    assert g.keeper.follow(end + SETTLE_S, g.robot.home_pose).end.outcome == "GUARD_STOPPED"
    held = Goal(robot)
    held.keeper.tripped(trip, True, 0.5, "force guard tripped")
    assert held.goal.watch.until == 0.5 and held.keeper.follow(0.5 + SETTLE_S, robot.home_pose).end.outcome == \
        "GUARD_STOPPED"
    blind = Goal(robot)
    blind.keeper.tripped(trip.__class__(**{**trip.__dict__, "which": "estimates", "stop": None}), False, 0.3, "blind")
    assert (blind.goal.watch.why, blind.goal.watch.until) == ("PAUSED", MOVE_S)  # the guard's move's end
    assert blind.keeper.follow(10.0, robot.home_pose) is None  # a pause never ends the goal at its stop's end
    blind.keeper.resumed(12.0)
    assert (blind.goal.watch.phase, blind.goal.watch.until) == ("moving", 12.0)
    blind.keeper.resume_failed(StewartError("the robot is gone"))
    assert blind.keeper.last_target is None
    assert blind.keeper.follow(12.0, robot.home_pose).end == MoveEnd(
        "INTERNAL_ERROR", "the move could not resume after a pause: the robot is gone")


def test_the_robots_own_stop_ends_the_goal_once_and_abandons_its_target(robot):
    g = Goal(robot)
    stop = g.keeper.on_robot_status("", 0.5, "emergency_stop", "emergency stop pressed", STRUT_STOP_CAUSES)
    assert stop == RobotStop("emergency stop pressed", np.round(g.target, 5).tolist())
    assert g.guard.move is None and g.keeper.last_target is None
    assert g.keeper.follow(0.6, robot.home_pose).end == MoveEnd(
        "EMERGENCY_STOPPED", "the robot stopped the move itself (emergency stop pressed)")
    # the robot is back and a new goal runs: the same stop reported again (a latched status) does not end it
    again = g.keeper.begin(object(), g.request, robot.home_pose, 1.0, TOLERANCES, g.send)
    assert g.keeper.on_robot_status("", 0.5, "emergency_stop", "repeated", STRUT_STOP_CAUSES) is None
    assert g.guard.move is not None and g.keeper.goal is again and again.watch.ended is None
    watchdog = Goal(robot)
    assert watchdog.keeper.on_robot_status("", 0.5, "watchdog", "no commands", STRUT_STOP_CAUSES) is None
    assert watchdog.guard.move is not None  # a ramp of the units alone leaves the struts' move running
    fault = watchdog.keeper.on_robot_status("diverged", None, None, "", STRUT_STOP_CAUSES)
    assert fault is not None and fault.why == "physics fault: diverged"
    assert watchdog.keeper.follow(0.6, robot.home_pose).end.outcome == "PHYSICS_FAULT"
    nothing = watchdog.keeper.on_robot_status("", 2.0, "deactivated", "deactivated", STRUT_STOP_CAUSES)
    assert nothing is None  # no move and no target left to abandon: nothing to report


def test_a_goal_waits_for_the_struts_until_they_rest_are_cancelled_or_a_deadline_passes(robot):
    keeper = GoalKeeper(robot, GuardSupervisor(ForceGuard(robot, 200.0, 15.0), 0.02))
    wait = keeper.wait_for_rest(object(), 10.0, 100.0)
    with pytest.raises(RefusedError):
        keeper.check_free()
    sim_end, wall_end = 10.0 + REST_WAIT_S, 100.0 + REST_WAIT_WALL_S
    assert wait.settled(False, False, False, sim_end, wall_end) is None
    assert wait.settled(True, False, False, sim_end + 1, wall_end) is True
    assert wait.settled(False, True, False, sim_end, wall_end) is True
    assert wait.settled(False, False, True, 10.0, 100.0) is False
    assert wait.settled(False, False, False, sim_end + 1e-6, 100.0) is False
    assert wait.settled(False, False, False, 10.0, wall_end + 1e-6) is False
    keeper.rest_wait_over()
    keeper.check_free()
    refusal = rest_refusal(1e-3)
    assert refusal.outcome == "STRUTS_NOT_AT_REST" and "drifts at 1.000 mm/s" in str(refusal)
    assert "drifts" not in str(rest_refusal(None))


def test_a_goal_ended_from_outside_is_over_once_and_not_resumed(robot):
    g = Goal(robot)
    ended = g.keeper.finish(MoveEnd("SHUTDOWN", "kinematics is shutting down"), 0.7)
    assert ended is g.goal and ended.duration == 0.7 and g.keeper.last_target is None
    assert g.keeper.finish(MoveEnd("SHUTDOWN", "again"), 0.8) is None
    with pytest.raises(ValueError):
        g.keeper.feedback(0.8, robot.home_pose)
