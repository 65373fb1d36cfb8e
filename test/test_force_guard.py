"""The force guard's supervisor driven by synthetic event streams (no ROS): joint states and wrench estimates
of a 10 mm lift into a load that stiffens with the lift, batch after batch on a stepped clock, and the actions
that come out (send this stop, report this trip, publish the status, resume the target) checked against the
load's closed form and the order the robot needs them in."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration import inverse_kinematics
from stewart_vibration.motion.estimate_watch import (
    CHECK_MEMORY_S,
    LAG_MEMORY_S,
    RESUME_FRESH_S,
    CheckGaps,
    EstimateWatch,
)
from stewart_vibration.motion.force_guard import MAX_STOP_RETRIES, WATCH_AFTER_S, ForceGuard
from stewart_vibration.motion.guard_supervisor import GuardSupervisor, PublishStatus, ResumeTarget, SendStop, Tripped
from stewart_vibration.motion.stop_planning import MAX_WINDOW_S

LIFT_M, DURATION_S, BATCH_S, STATE_HZ = 0.01, 2.0, 0.02, 500
BASE_N, LIMIT_N = 50.0, 200.0


def load_at(progress, growth_per_progress: float = 3.0):
    """The synthetic tissue: force (N) along z after ``progress`` of the lift, exponential stiffening."""
    return BASE_N * np.exp(growth_per_progress * np.asarray(progress, float))


class Lift:
    """A guarded 10 mm lift from home begun at 0 s (the emulator's clock), its struts exactly on the plan
    until a stop is sent; then they follow the stop's quintic to rest (rest at its end is all these tests use)."""

    def __init__(self, robot, limit: float = LIMIT_N, max_estimate_age: float = 0.25):
        self.robot = robot
        self.guard = ForceGuard(robot, limit, 0.0, max_estimate_age=max_estimate_age)
        self.supervisor = GuardSupervisor(self.guard, BATCH_S)
        self.goal_pose = robot.home_pose + [0, 0, LIFT_M, 0, 0, 0]
        self.start = inverse_kinematics(robot, robot.home_pose)
        self.goal = inverse_kinematics(robot, self.goal_pose)
        self.supervisor.on_wrenches([0.0], [[0, 0, BASE_N, 0, 0, 0]], 0.0, None, False)
        self.guard.begin_move(0.0, DURATION_S, self.start, self.goal, robot.home_pose, self.goal_pose)
        self.stop: SendStop | None = None

    def progress(self, stamps):
        if self.stop is not None:  # held where the stop brings them (its quintic's end)
            return np.full(len(stamps), self.stop.stop.progress)
        return self.guard.move.progress(stamps)[0] if self.guard.move is not None else np.ones(len(stamps))

    def lengths(self, stamps):
        return self.start + np.outer(self.progress(stamps), self.goal - self.start)

    def batch(self, t0: float, wrenches: bool = True, load: float | None = None, target: bool = False) -> list:
        """One batch (BATCH_S) of states and, unless ``wrenches`` is False, estimates at the same stamps."""
        stamps = t0 + np.arange(1, int(BATCH_S * STATE_HZ) + 1) / STATE_HZ
        self.supervisor.states_read(stamps, self.lengths(stamps))
        actions = []
        if wrenches:
            force = load_at(self.progress(stamps)) if load is None else np.full(len(stamps), load)
            w = np.zeros((len(stamps), 6))
            w[:, 2] = force
            actions += self.supervisor.on_wrenches(stamps, w, float(stamps[-1]), float(stamps[-1]), target)
        actions += self.supervisor.on_states(float(stamps[-1]), float(stamps[-1]))
        for action in actions:
            if isinstance(action, SendStop):
                self.stop = action
        return actions


def run(lift: Lift, until: float, **batch) -> list[tuple[float, object]]:
    """Batches from the lift's clock up to ``until`` (s); the actions with the batch's end time."""
    out = []
    for t0 in np.arange(0.0, until, BATCH_S):
        out += [(t0 + BATCH_S, action) for action in lift.batch(t0, **batch)]
    return out


def test_a_lift_into_stiffening_tissue_trips_before_the_limit_and_sends_its_stop_first(robot):
    """The load reaches the 200 N limit at progress ln(4)/3 = 0.46; the supervisor sends the stop and then
    reports the trip (the robot must get the stop before anything else), once; the load where the stop ends is
    within 5 % of the limit and the load when it tripped below it; after the stop and WATCH_AFTER_S one status
    carries the final peak."""
    lift = Lift(robot)
    actions = run(lift, DURATION_S + 1.0)
    kinds = [type(a) for _t, a in actions]
    assert kinds == [SendStop, Tripped, PublishStatus], kinds
    (t_stop, send), (_, tripped), (t_status, _) = actions
    trip = tripped.trip
    assert send.stop is trip.stop and send.by == "guard" and send.attempt == 0 and not tripped.held
    assert trip.which == "force" and trip.force < LIMIT_N
    assert load_at(trip.stop.progress) <= 1.05 * LIMIT_N
    assert trip.stop.progress < np.log(LIMIT_N / BASE_N) / 3.0 + 0.05  # not far past where the load meets the limit
    assert t_status >= trip.stop.receipt_time + trip.stop.duration + WATCH_AFTER_S - BATCH_S
    assert lift.guard.peak[0] == pytest.approx(load_at(trip.stop.progress), rel=1e-6)


def test_a_load_that_stays_under_the_limit_calls_for_nothing(robot):
    lift = Lift(robot, limit=1e4)
    assert run(lift, DURATION_S + 1.0) == []
    assert not lift.guard.tripped and lift.guard.move is None  # watched to its end and let go


def test_estimates_that_stop_pause_the_move_and_fresh_ones_resume_it_once(robot):
    """No estimate after 0 s: at 0.25 s of age the move pauses (an "estimates" trip with its stop); estimates
    fresh again for RESUME_FRESH_S after the stop, with the load below the limit: one ResumeTarget, and only
    while the node has a target. The freshness counts whether or not there is one: a target given after the
    estimates kept up resumes at once."""
    lift = Lift(robot)
    actions = run(lift, 0.4, wrenches=False)
    assert [type(a) for _t, a in actions] == [SendStop, Tripped]
    t_blind, tripped = actions[1]
    assert tripped.trip.which == "estimates" and 0.25 < t_blind <= 0.25 + 2 * BATCH_S
    stop = tripped.trip.stop
    t = stop.receipt_time + stop.duration + 0.1
    quiet = []
    for t0 in np.arange(t, t + RESUME_FRESH_S + 0.1, BATCH_S):
        quiet += lift.batch(t0, load=100.0, target=False)
    assert quiet == [PublishStatus()]  # the stop is over (its peak); fresh long enough, but nothing to resume
    resumed = lift.batch(t + RESUME_FRESH_S + 0.2, load=100.0, target=True)
    assert resumed == [ResumeTarget()]
    assert not lift.guard.tripped


def test_a_load_found_over_the_limit_when_estimates_return_is_a_held_trip(robot):
    """The load the guard could not see passed the limit meanwhile: no resume, a force trip reported as held by
    the pause's stop (no new stop: the struts are at rest already), once."""
    lift = Lift(robot)
    run(lift, 0.4, wrenches=False)
    stop = lift.guard.trip.stop
    t = stop.receipt_time + stop.duration + 0.1
    actions = []
    for t0 in np.arange(t, t + RESUME_FRESH_S + 0.3, BATCH_S):
        actions += lift.batch(t0, load=250.0, target=True)
    assert [type(a) for a in actions] == [PublishStatus, Tripped]  # the stop is over, then the load is judged
    assert actions[1].held and actions[1].trip.which == "force" and actions[1].trip.force == 250.0


def test_estimates_queued_behind_a_stall_are_read_before_the_guard_judges_it_blind(robot):
    """After a stall of the node, states and estimates arrive together: the estimates read between
    ``states_read`` and ``on_states`` are newer news than their absence, so no blind stop; without them the
    same states pause the move."""
    for with_estimates, expected in ((True, []), (False, [SendStop, Tripped])):
        lift = Lift(robot)
        stamps = 0.5 + np.arange(1, 11) / STATE_HZ  # 0.5 s of silence, then a batch
        lift.supervisor.states_read(stamps, lift.lengths(stamps))
        actions = []
        if with_estimates:
            w = np.zeros((len(stamps), 6))
            w[:, 2] = load_at(lift.progress(stamps))
            actions += lift.supervisor.on_wrenches(stamps, w, float(stamps[-1]), float(stamps[-1]), True)
        actions += lift.supervisor.on_states(float(stamps[-1]), float(stamps[-1]))
        assert [type(a) for a in actions] == expected


@pytest.mark.parametrize("by", ["guard", "cancel"])
def test_a_refused_stop_is_sent_again_over_a_doubled_window_until_the_retries_are_used_up(robot, by):
    """A stop the robot refused (it arrived too late to be taken) is planned again further along, each attempt
    numbered and its reason kept for the log; after MAX_STOP_RETRIES none (the guard's own stop and a cancel's
    alike)."""
    lift = Lift(robot)
    if by == "guard":
        run(lift, 0.4, wrenches=False)
        first = lift.guard.trip.stop
    else:
        run(lift, 0.6)
        first = lift.guard.cancel(0.6)
    attempt, progress, now = 0, first.progress, 0.7
    for _ in range(MAX_STOP_RETRIES):
        actions = lift.supervisor.on_stop_refused(by, attempt, now, "arrived 0.3 s late")
        assert len(actions) == 1 and isinstance(actions[0], SendStop)
        send = actions[0]
        assert send.by == by and send.attempt == attempt + 1 and "arrived 0.3 s late" in send.why
        assert send.stop.progress > progress
        attempt, progress, now = send.attempt, send.stop.progress, now + 0.02
    assert lift.supervisor.on_stop_refused(by, attempt, now, "late again") == []


def test_the_estimate_watch_keeps_the_largest_lag_of_its_memory_and_the_speed_it_allows():
    """Lag = newest state stamp - newest estimate stamp, the largest over LAG_MEMORY_S; speed = blind_travel /
    lag (1 ms floor); none before an estimate; the age of the load since a move's start if that is later."""
    watch = EstimateWatch(max_estimate_age=0.25, blind_travel=1.5e-3)
    assert watch.lag == 0.0 and watch.speed_limit() == np.inf and not watch.heard
    watch.checked(1.0)  # no estimate yet: nothing remembered
    assert watch.lag == 0.0
    watch.arrived([0.5, 0.7])
    watch.checked(1.0)
    assert watch.heard and watch.newest == 0.7 and watch.lag == pytest.approx(0.3)
    assert watch.speed_limit() == pytest.approx(1.5e-3 / 0.3)
    assert watch.age(1.0, since=0.9) == pytest.approx(0.1) and watch.age(1.0, since=0.0) == pytest.approx(0.3)
    watch.arrived([1.0])
    watch.checked(1.0 + LAG_MEMORY_S - 0.01)  # the 0.3 s lag at 1.0 s is still remembered
    assert watch.lag == pytest.approx(LAG_MEMORY_S - 0.01)
    last = 1.0 + 2 * LAG_MEMORY_S  # more than LAG_MEMORY_S after both earlier checks: they leave the memory
    watch.arrived([last])
    watch.checked(last)
    assert watch.lag == 0.0 and watch.speed_limit() == pytest.approx(1.5e-3 / 1e-3)


def test_the_estimates_keep_up_only_without_a_break():
    """kept_up: fresh (within half of max_estimate_age) for RESUME_FRESH_S without a break; a stale check or a
    reset starts the count again."""
    watch = EstimateWatch(max_estimate_age=0.2)
    for t in np.arange(0.0, RESUME_FRESH_S, 0.05):
        watch.arrived([t])
        assert not watch.kept_up(t + 0.09)  # 90 ms behind: fresh, not yet long enough
    watch.arrived([RESUME_FRESH_S])
    assert watch.kept_up(RESUME_FRESH_S + 0.09)
    assert not watch.kept_up(RESUME_FRESH_S + 0.2)  # 0.2 s behind: stale, the count restarts
    watch.arrived([RESUME_FRESH_S + 0.2])
    assert not watch.kept_up(RESUME_FRESH_S + 0.2)
    watch.reset_freshness()
    watch.arrived([2 * RESUME_FRESH_S + 0.3])
    assert not watch.kept_up(2 * RESUME_FRESH_S + 0.3)


def test_check_gaps_are_the_largest_recent_gap_capped_at_the_longest_window():
    gaps = CheckGaps()
    assert gaps.gap == 0.0
    for t in (0.0, 0.02, 0.04, 0.24, 0.26):
        gaps.checked(t)
    assert gaps.gap == pytest.approx(0.2)
    gaps.checked(0.26 + CHECK_MEMORY_S)  # 0.0 .. 0.24 have left the memory; the gap since 0.26 counts, capped
    assert gaps.gap == pytest.approx(MAX_WINDOW_S)
    gaps.checked(0.28 + CHECK_MEMORY_S)  # now 0.26 has left too: only the last 20 ms gap remains
    assert gaps.gap == pytest.approx(0.02)
