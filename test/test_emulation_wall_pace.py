"""WallPace (emulation.wall_pace) on a stepped wall clock: sim time keeps real_time_factor x wall time,
waking once per pace period; a thread that falls far behind keeps the pace from there instead of racing, one
a little behind catches up; a restart (a new rate, a wait for consumers) counts from that instant."""

from __future__ import annotations

import pytest

from stewart_vibration.emulation.wall_pace import WallPace, state_periods

PERIOD = 0.002  # state period (s of sim time): 500 Hz
WAKEUP_EVERY = 10  # state periods per wake-up (a 20 ms pace period)


class SteppedWall:
    """A wall clock that moves only when the code sleeps or a test says the work took time (s)."""

    def __init__(self):
        self.t = 0.0
        self.slept: list[float] = []

    def __call__(self):
        return self.t

    def sleep(self, seconds):
        self.slept.append(seconds)
        self.t += seconds


def run(pace: WallPace, wall: SteppedWall, until_wall_s: float, cost_s: float = 0.0, stall=None) -> int:
    """The physics thread's use of ``pace``: periods of PERIOD, each costing ``cost_s`` of wall time, a wake-up
    every WAKEUP_EVERY; ``stall(done)`` may add wall time. Returns the periods run before the wall clock reaches
    ``until_wall_s``."""
    sim, done = 0.0, 0
    pace.start(sim)
    while wall.t < until_wall_s - 1e-12:
        sim += PERIOD
        done += 1
        wall.t += cost_s + (stall(done) if stall else 0.0)
        spent = pace.measure(sim)
        if done % WAKEUP_EVERY == 0:
            pace.wake_up(sim, spent)
    return done


@pytest.mark.parametrize(("duration_s", "rate_hz", "periods"), [(0.02, 500.0, 10), (0.02, 1000.0, 20),
                                                                (0.0, 500.0, 1), (0.0005, 500.0, 1)])
def test_state_periods_per_wakeup_by_hand(duration_s, rate_hz, periods):
    assert state_periods(duration_s, rate_hz) == periods


@pytest.mark.parametrize(("rtf", "periods"), [(1.0, 500), (2.0, 1000), (0.5, 250)])
def test_one_wall_second_runs_rtf_seconds_of_sim_time(rtf, periods):
    """Free physics: 1 s of wall time holds rtf s of sim time = rtf * 500 periods, slept in 50 * rtf equal
    naps of 20 ms / rtf."""
    wall = SteppedWall()
    pace = WallPace(rtf, clock=wall, sleep=wall.sleep)
    assert run(pace, wall, 1.0) == periods
    assert wall.slept == pytest.approx([0.02 / rtf] * (periods // WAKEUP_EVERY))


def test_physics_that_costs_wall_time_sleeps_only_the_rest():
    """Each 2 ms period costs 1.5 ms: a wake-up after 10 sleeps 5 ms; the achieved factor stays 1."""
    wall = SteppedWall()
    pace = WallPace(1.0, clock=wall, sleep=wall.sleep)
    assert run(pace, wall, 1.0, cost_s=0.0015) == 500
    assert wall.slept == pytest.approx([0.005] * 50)
    assert pace.achieved_rtf == pytest.approx(1.0, abs=0.01)


def test_as_fast_as_possible_never_sleeps():
    wall = SteppedWall()
    pace = WallPace(0.0, clock=wall, sleep=wall.sleep)
    assert run(pace, wall, 0.1, cost_s=0.0001) == 1000
    assert wall.slept == []
    assert pace.achieved_rtf == pytest.approx(20.0)  # 2 ms of sim per 0.1 ms of wall


def test_a_long_stall_keeps_the_pace_from_there_without_racing():
    """0.6 s lost in period 100 (beyond MAX_BEHIND_S), a wake-up that would have slept 20 ms: one reset, and the
    other 0.58 s are lost for good -- 1.6 s of wall time hold 800 - 290 = 510 periods; every later wake-up
    sleeps its full 20 ms (no burst to catch up)."""
    wall = SteppedWall()
    pace = WallPace(1.0, clock=wall, sleep=wall.sleep)
    done = run(pace, wall, 1.6, stall=lambda done: 0.6 if done == 100 else 0.0)
    assert pace.behind_resets == 1
    assert done == 510
    assert wall.slept[9:] == pytest.approx([0.02] * 41)  # 9 naps before the stall, none in it


def test_a_short_stall_is_caught_up():
    """0.4 s lost in period 100 (within MAX_BEHIND_S): no reset; that wake-up and the next 19 (0.38 s of sim
    time) run without sleeping, so sim time is back on the wall clock: 1.4 s of wall time hold 700 periods, 50
    of their 70 wake-ups sleep."""
    wall = SteppedWall()
    pace = WallPace(1.0, clock=wall, sleep=wall.sleep)
    done = run(pace, wall, 1.4, stall=lambda done: 0.4 if done == 100 else 0.0)
    assert pace.behind_resets == 0
    assert done == 700
    assert len([nap for nap in wall.slept if nap > 1e-9]) == 70 - 20  # a nap of 1e-16 s is float rounding


def test_a_restart_counts_the_new_rate_from_that_instant():
    """At 1x for 0.1 s, then 2x from a restart: the restart's wake-up does not sleep; the next ones sleep 10 ms."""
    wall = SteppedWall()
    pace = WallPace(1.0, clock=wall, sleep=wall.sleep)
    run(pace, wall, 0.1)
    pace.real_time_factor = 2.0
    pace.restart()
    sim = 0.1
    naps = []
    for _ in range(3):
        sim += WAKEUP_EVERY * PERIOD
        naps.append(pace.wake_up(sim, pace.measure(sim)))
    assert naps == pytest.approx([0.0, 0.01, 0.01])
    assert wall.t == pytest.approx(0.12)


def test_start_drops_a_restart_asked_before():
    wall = SteppedWall()
    pace = WallPace(1.0, clock=wall, sleep=wall.sleep)
    pace.restart()
    pace.start(5.0)
    assert pace.wake_up(5.02, pace.measure(5.02)) == pytest.approx(0.02)
