"""The force guard's supervisor driven by event streams (no ROS): synthetic ones (joint states and wrench
estimates of a 10 mm lift into a load that stiffens with the lift, batch after batch on a stepped clock, the
actions that come out checked against the load's closed form and the order the robot needs them in), and one
recorded from a real run of the tissue scenario (test/data/guard_trip_events.npz, written by
tools/record_guard_events.py), replayed to check that the supervisor makes the decision the running node made."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from stewart_vibration import forward_kinematics, inverse_kinematics
from stewart_vibration.motion.estimate_watch import (
    CHECK_MEMORY_S,
    LAG_MEMORY_S,
    RESUME_FRESH_S,
    CheckGaps,
    EstimateWatch,
)
from stewart_vibration.motion.force_guard import MAX_STOP_RETRIES, WATCH_AFTER_S, ForceGuard
from stewart_vibration.motion.guard_parameters import guard_from_parameters
from stewart_vibration.motion.guard_supervisor import GuardSupervisor, PublishStatus, ResumeTarget, SendStop, Tripped
from stewart_vibration.motion.stop_planning import MAX_WINDOW_S, RECEIPT_DELAY_S

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


# -- a recorded guarded move ----------------------------------------------------------------------------------
RECORDED = Path(__file__).resolve().parent / "data" / "guard_trip_events.npz"
TRIP_TIME_TOL_S = 0.01  # half the 20 ms between the estimator's bursts: the replay trips with the batch the node did
TRIP_FORCE_REL = 0.02  # the load rises ~2.6 % per burst at the trip: the estimate the node tripped on, not the next
PREDICTED_REL = 0.05  # each estimate's fitted progress hangs on how far the node had read the states then, which
#                       the recorder's order gives to within one /clock period (10 ms)
STOP_END_TOL_M = 5e-5  # a quarter of the ~0.2 mm the struts move in one burst at the move's peak rate
PEAK_REL = 0.01  # the largest recorded estimate over a stop that ends within a few ms of the node's


@pytest.fixture(scope="module")
def recorded():
    with np.load(RECORDED) as data:
        return {name: data[name] for name in data.files}


def _read_place(data: dict, splitting: np.ndarray, last_pose: int) -> int:
    """Where the node read a timer batch whose last pose estimate is at ``last_pose`` (in the recorder's order):
    there, or before the burst of estimates the recorder was taking then (the estimator publishes a burst back
    to back, the recorder logs it with one time, the node takes it whole)."""
    seq, log = data["wrench_seq"], data["wrench_log_ns"]
    at = int(np.searchsorted(seq, last_pose))  # the first estimate after the pose estimates

    def together(a: int, b: int) -> bool:  # estimates a < b of one burst: one log time, nothing but ours between
        return log[a] == log[b] and np.searchsorted(splitting, seq[a]) == np.searchsorted(splitting, seq[b])

    if not (0 < at < seq.size and seq[at] == last_pose + 1 and together(at - 1, at)):
        return last_pose
    while at > 0 and together(at - 1, at):
        at -= 1
    return int(seq[at]) - 1


def state_reads(data: dict, batch_size: int) -> list[tuple[float, str, float]]:
    """When the node read which states: (place in the recorder's order, "read", how many of the recorded states
    it had read then). See NodeReplay."""
    splitting = np.sort(np.concatenate([data["states_seq"], data["clock_seq"], [data["move_seq"], data["stop_seq"]]]))
    poses = data["pose_seq"]
    runs = np.split(np.arange(poses.size), np.flatnonzero(np.diff(np.searchsorted(splitting, poses))) + 1)
    reads: list[tuple[float, str, float]] = []
    for run in runs:
        count = int(np.searchsorted(data["states_stamp"], data["pose_stamp"][run[-1]], side="right"))
        if not count:  # states read before the recording's window
            continue
        if run.size >= batch_size:  # read as its newest state arrived
            place = int(data["states_seq"][count - 1])
        else:  # by the timer: where the node had published the pose estimates
            place = _read_place(data, splitting, int(poses[run[-1]]))
        reads.append((place + 0.5, "read", count))
    return reads


class NodeReplay:
    """The kinematics node's side of the guard (nodes/kinematics_node.py) fed from a recording, in the order the
    recorder received the messages (the fixture's ``*_seq``).

    The node takes wrench estimates in batches of ``batch_size`` (judged on the 10th; the ones queued also
    whenever it reads states) and reads states in batches (on the 10th, or on a wall-clock timer), and what it
    predicts for a burst of estimates depends on which states it had read by then: an estimate newer than the
    newest state read is fitted at that state's progress (a few ms make tens of N). The recorded states do not
    say when the node read them; the node's own pose estimates do: one per state read, published as it read
    them, so a run of them in the recorder's order is one batch (estimates the recorder got meanwhile do not
    split it: the estimator's messages cross the node's on the way). A batch of ``batch_size`` was read as its
    newest state arrived (the pose estimates' place is their transit from the node, often after the burst the
    estimator computed from the same states); a smaller one, the wall-clock timer's, where the node published
    its pose estimates (before a burst the recorder was getting then: the estimator publishes a burst back to
    back, the node takes it whole). The node's "now" is ``emulator_now``: the newer of the newest state read and
    the newest /clock heard, which is what its stop is planned from (a burst is often judged at a /clock past
    the newest state read, so the stamps alone would plan another stop). The move is begun as
    ``move_server.move_to`` began it: at the trajectory's place, from the newest state read and pose estimate,
    to the trajectory's last point over its last point's time, estimated to start RECEIPT_DELAY_S after "now";
    its goal pose is the nominal robot's FK of its goal lengths."""

    def __init__(self, robot, data: dict, force_limit: float | None = None):
        params = dict(zip(data["param_names"].tolist(), data["param_values"].tolist()))
        if force_limit is not None:
            params["guard_force_n"] = force_limit
        self.robot, self.data, self.batch_size = robot, data, int(params["batch_size"])
        self.guard = guard_from_parameters(robot, params)
        self.supervisor = GuardSupervisor(self.guard, params["batch_period_s"])
        self.clock, self.read = -np.inf, 0
        self.state_time: float | None = None  # the newest state read (s)
        self.pending: list[int] = []  # estimates queued, not yet judged (indices)
        self.actions: list[tuple[float, object]] = []  # (the node's "now", action)

    def now(self) -> float:
        return self.clock if self.state_time is None else max(self.state_time, self.clock)

    def run(self, until_seq: float = np.inf) -> list[tuple[float, object]]:
        """Replay every event before ``until_seq`` (a place in the recorder's order); the actions."""
        d = self.data
        events: list[tuple[float, str, float]] = [(int(s), "clock", float(t))
                                                  for s, t in zip(d["clock_seq"], d["clock_stamp"])]
        events += [(int(s), "estimate", i) for i, s in enumerate(d["wrench_seq"])]
        events += [(int(d["move_seq"]), "move", 0), *state_reads(d, self.batch_size)]
        events.sort(key=lambda event: event[0])
        for place, kind, what in events:
            if place >= until_seq:
                break
            if kind == "clock":
                self.clock = max(self.clock, what)
            elif kind == "estimate":
                self.pending.append(int(what))
                if len(self.pending) >= self.batch_size:
                    self.judge_estimates()
            elif kind == "read":
                self.read_states(int(what))
            else:
                self.begin_move()
        return self.actions

    def read_states(self, count: int) -> None:
        """KinematicsNode._solve: the states up to ``count`` read, the estimates queued judged, then the states."""
        d, first = self.data, self.read
        if count <= first:
            return
        self.supervisor.states_read(d["states_stamp"][first:count], d["states_legs"][first:count])
        self.state_time, self.read = float(d["states_stamp"][count - 1]), count
        self.judge_estimates()
        self.actions += [(self.now(), a) for a in self.supervisor.on_states(self.now(), self.state_time)]

    def judge_estimates(self) -> None:
        """KinematicsNode.process_wrenches for the estimates queued."""
        if not self.pending:
            return
        d, batch, self.pending = self.data, np.array(self.pending), []
        self.actions += [(self.now(), a) for a in self.supervisor.on_wrenches(
            d["wrench_stamp"][batch], d["wrench_values"][batch], self.now(), self.state_time, False)]

    def begin_move(self) -> None:
        d = self.data
        start, goal = d["states_legs"][self.read - 1], d["move_positions"][-1]
        goal_pose = forward_kinematics(self.robot, goal, guess=d["start_pose"]).pose
        self.guard.begin_move(self.now() + RECEIPT_DELAY_S, float(d["move_times"][-1]), start, goal, d["start_pose"],
                              goal_pose)


def test_the_recording_is_the_tissue_scenarios_guarded_move_with_its_parameters(recorded):
    """What the fixture says it is: the tissue scenario's run, a force trip the node reported with the limit of
    the parameters recorded beside it, predicting a load over that limit from a load under it."""
    source = json.loads(str(recorded["source"]))
    assert source["scenario"] == "tissue_distraction_vibration_guard" and source["mcap"].endswith(".mcap")
    params = dict(zip(recorded["param_names"].tolist(), recorded["param_values"].tolist()))
    assert set(recorded["status_trip_limit"]) == {"force"}
    assert (recorded["status_force_limit_n"] == params["guard_force_n"]).all()
    assert recorded["status_predicted_force_n"][0] > params["guard_force_n"] > recorded["status_trip_force_n"][0]


def test_the_recorded_guarded_move_trips_on_force_as_the_node_did(robot, recorded):
    """The 12 mm distraction of the tissue scenario, replayed through the supervisor: it trips on force with the
    burst the node tripped on, predicting about the load the node predicted, sends its stop before it reports
    the trip, and the stop ends where the node's ended; after the stop one status with the peak the node
    published. Every reference is what the node recorded (kinematics/guard_status, legs/joint_trajectory)."""
    node = NodeReplay(robot, recorded)
    actions = [a for _now, a in node.run()]
    assert [type(a) for a in actions] == [SendStop, Tripped, PublishStatus], actions
    send, tripped = actions[0], actions[1]
    trip, first = tripped.trip, 0  # the status the node published with its trip
    assert send.stop is trip.stop and send.by == "guard" and send.attempt == 0 and not tripped.held
    assert trip.which == "force" and trip.limit == recorded["status_force_limit_n"][first]
    assert trip.time == pytest.approx(recorded["status_trip_time_s"][first], abs=TRIP_TIME_TOL_S)
    assert trip.force == pytest.approx(recorded["status_trip_force_n"][first], rel=TRIP_FORCE_REL)
    assert trip.predicted_force == pytest.approx(recorded["status_predicted_force_n"][first], rel=PREDICTED_REL)
    np.testing.assert_allclose(send.stop.lengths, recorded["stop_positions"][-1], atol=STOP_END_TOL_M)
    # the goal pose the replay derives (FK of the goal lengths, converged to 1e-12 m) is the node's target
    np.testing.assert_allclose(trip.goal_pose, recorded["status_tripped_goal"][first], atol=1e-9)
    assert node.guard.peak[0] == pytest.approx(recorded["status_peak_force_n"][-1], rel=PEAK_REL)


@pytest.mark.parametrize("limit_of_recorded, trips", [(1.1, False), (0.5, True)])
def test_the_replayed_decision_hinges_on_the_limit(robot, recorded, limit_of_recorded, trips):
    """The test can tell: up to the stop the node sent, the same stream with a limit 10 % above the load the
    node predicted (twice the tolerance on it) calls for nothing, and with half the node's limit it trips
    earlier than the node did, beyond the tolerance on the trip's time (a prediction can jump past a limit
    from one burst to the next, so a limit only a little lower may trip with the same burst)."""
    limit = limit_of_recorded * (recorded["status_predicted_force_n"][0] if not trips else
                                 recorded["status_force_limit_n"][0])
    actions = NodeReplay(robot, recorded, force_limit=limit).run(until_seq=int(recorded["stop_seq"]))
    trip_times = [a.trip.time for _now, a in actions if isinstance(a, Tripped)]
    if not trips:
        assert actions == []
    else:
        assert trip_times and trip_times[0] < recorded["status_trip_time_s"][0] - TRIP_TIME_TOL_S
