"""The emulator's physics thread without ROS (emulation.physics_thread), on an in-process emulator and a
stepped wall clock: what each state period hands out and when, how many periods a second of wall time holds
at real time and as fast as the consumers allow, a block that raises latching a fault that holds the robot
(and the loop going on), and the brake to rest before physics stops, bounded in wall time."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from stewart_vibration import inverse_kinematics
from stewart_vibration.emulation.emulator import HardwareEmulator
from stewart_vibration.emulation.physics_thread import PACE_PARAMETERS, BlockSchedule, PhysicsPacing, PhysicsThread
from stewart_vibration.emulation.vibration_status import SHUTDOWN
from stewart_vibration.robot import LEG_NAMES
from stewart_vibration.sim.mjcf import load_simulation_settings

PERIOD = 0.002  # 500 Hz states
# /clock at 100 Hz, markers at 10 Hz, status every 0.1 s, a wake-up every 20 ms
SCHEDULE = BlockSchedule.from_rates(500.0, 100.0, 10.0, 0.1, 0.02)


class SteppedWall:
    """A wall clock (s) that moves only when the code sleeps; ``on_sleep(t)`` runs after each sleep."""

    def __init__(self):
        self.t = 0.0
        self.slept: list[float] = []
        self.on_sleep = None

    def __call__(self):
        return self.t

    def sleep(self, seconds):
        self.slept.append(seconds)
        self.t += seconds
        if self.on_sleep is not None:
            self.on_sleep(self.t)


class Outputs:
    """Records what the thread hands out (with the wall time) and stops it once ``stop(outputs)`` is true."""

    def __init__(self, physics: PhysicsThread, wall: SteppedWall, stop):
        self.physics, self.wall, self.stop = physics, wall, stop
        self.blocks: list = []  # (wall s, Block)
        self.failures: list = []
        self.pace_reports: list[float] = []

    def publish_block(self, block):
        self.blocks.append((self.wall.t, block))
        if self.stop(self):
            self.physics.running = False

    def block_failed(self, failure):
        self.failures.append(failure)
        if self.stop(self):
            self.physics.running = False

    def report_pace(self, sim_time, pacing):
        self.pace_reports.append(sim_time)


@pytest.fixture
def emulator(robot, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo may write MUJOCO_LOG.TXT in the working directory
    return HardwareEmulator(robot, load_simulation_settings(timestep=1 / 2000))


def physics_on(emulator, wall, rtf=1.0, max_consumer_lag_s=None, schedule=SCHEDULE) -> PhysicsThread:
    """Physics at ``rtf`` on ``wall``, waiting for consumers more than ``max_consumer_lag_s`` (s) behind (None:
    no consumers heard)."""
    pacing = PhysicsPacing(rtf, max_consumer_lag_s or 0.0, lockstep=False, clock=wall, sleep=wall.sleep)
    return PhysicsThread(emulator, threading.Lock(), schedule, pacing,
                         paced_by_consumers=lambda: max_consumer_lag_s is not None, clock=wall, sleep=wall.sleep)


def run(physics, wall, stop) -> Outputs:
    """``PhysicsThread.run`` on this thread until ``stop(outputs)``."""
    outputs = Outputs(physics, wall, stop)
    physics.running = True
    physics.run(outputs.publish_block, outputs)
    return outputs


def move_up(robot, emulator, dz=0.002, duration_s=1.0):
    """Command the struts toward the home pose raised by ``dz`` (m) over ``duration_s``; returns the lengths."""
    pose = robot.home_pose.copy()
    pose[2] += dz
    lengths = inverse_kinematics(robot, pose)
    emulator.command_struts(LEG_NAMES, 0.0, np.array([duration_s]), lengths[None, :])
    return lengths


def test_the_schedule_counts_state_periods_by_hand():
    assert SCHEDULE == BlockSchedule(period_s=0.002, clock_every=5, marker_every=50, status_every=50,
                                     wakeup_every=10)
    no_markers = BlockSchedule.from_rates(500.0, 1000.0, 0.0, 0.0001, 0.0)
    assert (no_markers.clock_every, no_markers.marker_every, no_markers.status_every, no_markers.wakeup_every) == (
        1, 0, 1, 1)  # nothing more often than the states, markers off


def test_at_real_time_one_wall_second_holds_500_periods_and_each_output_when_due(emulator):
    wall = SteppedWall()
    physics = physics_on(emulator, wall)
    t0 = emulator.time
    out = run(physics, wall, lambda o: o.wall.t >= 1.0 - 1e-9)  # sim and wall times add up in floats
    within = [block for t, block in out.blocks if t < 1.0 - 1e-9]
    assert len(within) == 1 + 500  # the state before the first period, then 500 periods of 2 ms
    assert within[-1].time == pytest.approx(t0 + 1.0)
    assert wall.slept == pytest.approx([0.02] * 50)  # one nap per wake-up, nothing else waits
    done = range(1, 501)
    periods = within[1:]
    assert [b.clock_due for b in periods] == [n % 5 == 0 for n in done]
    assert [b.markers_due for b in periods] == [n % 50 == 0 for n in done]
    assert [b.report is not None for b in periods] == [n % 50 == 1 for n in done]  # the first period, then 0.1 s
    assert within[0].clock_due and not within[0].markers_due and within[0].report is None
    assert out.pace_reports == pytest.approx([t0 + 1.0])  # after 500 periods
    assert physics.pacing.wall.achieved_rtf == pytest.approx(1.0, abs=0.03)


def test_as_fast_as_possible_never_sleeps_without_consumers_to_wait_for(emulator):
    wall = SteppedWall()
    physics = physics_on(emulator, wall, rtf=0.0)
    out = run(physics, wall, lambda o: len(o.blocks) > 1000)
    assert wall.t == 0.0 and wall.slept == []
    assert out.blocks[-1][1].time == pytest.approx(emulator.time)


def test_as_fast_as_possible_sim_time_stays_within_the_lag_of_a_slow_consumer(emulator):
    """The consumer's newest stamp follows the wall clock at half real time; allowed lag 0.1 s: sim time at any
    block is at most 0.1 s + one pace period (20 ms) ahead of it, and after 1 s of wall time it is at
    t0 + 0.5 + 0.1 s (half real time plus the lag), never run past."""
    wall = SteppedWall()
    physics = physics_on(emulator, wall, rtf=0.0, max_consumer_lag_s=0.1)
    consumers = physics.pacing.consumers
    t0 = emulator.time
    consumer_stamp = lambda t: t0 + 0.5 * t  # noqa: E731 - the consumer's output (s of sim time) at wall t
    consumers.heard("platform/pose_estimate", consumer_stamp(0.0))
    wall.on_sleep = lambda t: consumers.heard("platform/pose_estimate", consumer_stamp(t))
    out = run(physics, wall, lambda o: o.wall.t >= 1.0)
    ahead = [block.time - consumer_stamp(t) for t, block in out.blocks]
    assert max(ahead) <= 0.1 + 0.02 + 1e-9
    assert out.blocks[-1][1].time == pytest.approx(t0 + 0.6, abs=0.021)
    assert consumers.waits > 0 and consumers.gave_up == 0


def test_a_block_that_raises_latches_a_fault_that_holds_the_robot_and_time_goes_on(robot, emulator):
    """Mid-move, the third block raises: one failure, logged; the fault is latched with the exception named,
    handed out once as new with a status evaluated for it; every later period has the robot held still (the
    struts stopped short of the target, every joint at zero velocity) while sim time goes on."""
    wall = SteppedWall()
    target = move_up(robot, emulator)
    for _ in range(250):  # half way: the struts move at their top speed
        emulator.advance(PERIOD)
    advance, calls = emulator.advance, []

    def failing_advance(duration):
        calls.append(duration)
        if len(calls) == 3:
            raise RuntimeError("boom")
        return advance(duration)

    emulator.advance = failing_advance
    physics = physics_on(emulator, wall, rtf=0.0)
    out = run(physics, wall, lambda o: len(o.blocks) > 60)
    assert [(f.count, f.logged, f.latch_error) for f in out.failures] == [(1, True, None)]
    assert isinstance(out.failures[0].error, RuntimeError)
    assert wall.slept == [PERIOD]  # the failed period is waited out, not run
    fault = emulator.fault
    assert fault is not None and "RuntimeError in the physics thread: boom" in fault.reason
    new = [block for _, block in out.blocks if block.new_fault is not None]
    assert len(new) == 1 and new[0].new_fault is fault
    assert new[0].report is not None and new[0].report.fault == fault.reason
    after = [block for _, block in out.blocks if block.time >= new[0].time]
    times = [block.time for block in after]
    assert np.all(np.diff(times) > 0)
    for block in after:
        _, positions, velocities, _ = block.sensors[0]
        assert np.abs(velocities).max() == 0.0
        assert positions == pytest.approx(after[0].sensors[0][1])
    struts = np.asarray(after[-1].sensors[0][1])[:6]
    assert np.abs(struts - target).max() > 1e-4  # held where it was, not carried on to the target
    assert emulator.at_rest()


def test_failures_are_counted_and_logged_thinned_even_when_latching_fails(emulator):
    wall = SteppedWall()

    def boom(*_args):
        raise RuntimeError("boom")

    emulator.advance = boom
    emulator.latch_fault = lambda reason: boom()
    physics = physics_on(emulator, wall, rtf=0.0)
    out = run(physics, wall, lambda o: len(o.failures) >= 5)
    assert [(f.count, f.logged) for f in out.failures] == [(1, True), (2, True), (3, True), (4, False), (5, False)]
    assert all(isinstance(f.latch_error, RuntimeError) for f in out.failures)
    assert wall.slept == [PERIOD] * 5
    assert len(out.blocks) == 1  # only the state before the first period


def stepping(emulator, wall):
    """Physics in step with the stepped wall clock (1x): each sleep runs its wall time of state periods."""
    def run_periods(_t):
        for _ in range(int(round(wall.slept[-1] / PERIOD))):
            emulator.advance(PERIOD)
    return run_periods


def stays_alive(physics):
    """A physics thread that only stays alive until stopped (the test steps physics itself)."""
    def wait():
        while physics.running:
            time.sleep(0.001)
    return wait


def test_the_brake_brings_a_moving_robot_to_rest_within_its_acceleration_limit(robot, emulator):
    """Mid-move at top speed v, a shutdown brakes the struts along their path: never harder than
    strut_acceleration_max a (so no sooner than v / a), at rest when the commanded stop ends (seen at the next
    10 ms check), short of the target."""
    wall = SteppedWall()
    target = move_up(robot, emulator)
    for _ in range(250):
        emulator.advance(PERIOD)
    halted_at = emulator.time
    speed = np.abs(emulator.struts.sample(halted_at)[1]).max()
    wall.on_sleep = stepping(emulator, wall)
    physics = physics_on(emulator, wall)
    physics.start(stays_alive(physics))
    try:
        assert physics.brake_to_rest(SHUTDOWN, timeout_s=3.0)
    finally:
        physics.stop()
    assert emulator.at_rest()
    stop_end = emulator.struts.rest_time()
    limit = robot.limits.strut_acceleration_max
    assert stop_end - halted_at >= speed / limit
    _, _, accelerations = emulator.struts.sample(np.linspace(halted_at, stop_end, 200))
    assert np.abs(accelerations).max() <= limit * (1 + 1e-9)
    assert wall.t == pytest.approx(np.ceil((stop_end - halted_at) / 0.01 - 1e-9) * 0.01)
    assert emulator.status.report.event_outcome == "SHUTDOWN"  # the stop the brake commanded
    lengths = emulator.joint_state()[1][:6]
    assert np.abs(np.asarray(lengths) - target).max() > 1e-4


def test_the_brake_gives_up_after_its_wall_time(robot, emulator):
    """Physics that does not advance (a stalled machine): the brake polls every 10 ms for 3 s, then gives up."""
    wall = SteppedWall()
    move_up(robot, emulator)
    emulator.advance(0.1)
    physics = physics_on(emulator, wall)
    physics.start(stays_alive(physics))
    try:
        assert not physics.brake_to_rest(SHUTDOWN, timeout_s=3.0)
    finally:
        physics.stop()
    assert wall.t == pytest.approx(3.0, abs=0.011)
    assert len(wall.slept) == pytest.approx(300, abs=1)


def test_no_brake_without_a_running_physics_thread(robot, emulator):
    """Nothing runs physics (never started, or its thread died): the brake returns at once and stops nothing."""
    wall = SteppedWall()
    move_up(robot, emulator)
    physics = physics_on(emulator, wall)
    assert physics.brake_to_rest(SHUTDOWN, timeout_s=3.0)
    physics.start(lambda: None)
    physics.thread.join()
    assert physics.brake_to_rest(SHUTDOWN, timeout_s=3.0)
    assert wall.t == 0.0 and not emulator.at_rest()  # still moving: no stop was commanded
    physics.stop()


def test_the_pacing_parameters_are_live_node_parameters_and_a_new_rate_counts_from_the_next_wakeup():
    from stewart_vibration.parameters.tables import HARDWARE_EMULATOR

    live = {spec.name for spec in HARDWARE_EMULATOR if not spec.at_configure and not spec.read_only}
    assert set(PACE_PARAMETERS) <= live
    wall = SteppedWall()
    pacing = PhysicsPacing(1.0, 0.1, lockstep=False, clock=wall, sleep=wall.sleep)
    pacing.wall.start(0.0)
    assert not pacing.waits_for_consumers()  # real time: the hardware does not wait for its software
    pacing.set("max_consumer_lag_s", 0.25)
    assert pacing.consumers.max_lag_s == 0.25
    assert pacing.wall.wake_up(0.02, 0.0) == pytest.approx(0.02)  # no restart: still paced from 0
    pacing.set("real_time_factor", 2.0)
    assert pacing.wall.wake_up(0.04, 0.0) == 0.0  # the restart: from here at 2x
    assert pacing.wall.wake_up(0.06, pacing.wall.measure(0.06)) == pytest.approx(0.01)
    assert pacing.waits_for_consumers()  # above real time
    pacing.set("real_time_factor", 1.0)
    pacing.set("lockstep", True)
    assert pacing.waits_for_consumers()
    with pytest.raises(KeyError):
        pacing.set("watchdog_s", 1.0)
