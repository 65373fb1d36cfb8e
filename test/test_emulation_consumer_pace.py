"""ConsumerPace (emulation.consumer_pace): above real time the emulator waits for late consumers, at most
max_wait_s, then runs past a stalled one until it catches up; at or below real time it never waits."""

from __future__ import annotations

import pytest

from stewart_vibration.emulation.consumer_pace import ConsumerPace, paces_consumers


class FakeWall:
    """A wall clock that advances only when the code under test sleeps (no real time spent)."""

    def __init__(self):
        self.t = 0.0
        self.on_sleep = None

    def sleep(self, seconds):
        self.t += seconds
        if self.on_sleep is not None:
            self.on_sleep(self.t)

    def __call__(self):
        return self.t


@pytest.mark.parametrize(("rtf", "paces"), [(0.0, True), (0.5, False), (1.0, False), (1.01, True), (2.0, True)])
def test_only_above_real_time_or_as_fast_as_possible(rtf, paces):
    assert paces_consumers(rtf) is paces


def test_a_consumer_within_the_lag_or_never_heard_is_not_waited_for():
    pace = ConsumerPace(max_lag_s=0.1)
    assert pace.behind(5.0) == {}  # nobody heard: maybe nobody is there
    pace.heard("a", 4.9)
    assert pace.behind(5.0) == {}  # exactly at the bound
    assert pace.behind(5.05) == {"a": pytest.approx(0.15)}
    assert ConsumerPace(max_lag_s=0.0).behind(1e9) == {}  # 0 = off


def test_the_wait_ends_when_the_consumer_catches_up():
    pace, wall = ConsumerPace(max_lag_s=0.1, max_wait_s=2.0), FakeWall()
    pace.heard("est", 1.0)
    pace.heard("kin", 1.3)
    # the late one reports 1.25 s after 0.5 s of wall time
    wall.on_sleep = lambda t: pace.heard("est", 1.25) if t >= 0.5 else None
    waited = pace.wait(1.3, lambda: True, sleep=wall.sleep, clock=wall)
    assert 0.5 <= waited < 0.51
    assert (pace.waits, pace.gave_up) == (1, 0)
    assert pace.wait(1.3, lambda: True, sleep=wall.sleep, clock=wall) == 0.0  # nobody late: no wait


def test_a_stalled_consumer_is_run_past_until_it_catches_up():
    pace, wall = ConsumerPace(max_lag_s=0.1, max_wait_s=2.0), FakeWall()
    pace.heard("est", 1.0)
    waited = pace.wait(2.0, lambda: True, sleep=wall.sleep, clock=wall)
    assert 2.0 <= waited < 2.01 and pace.gave_up == 1
    # while it stays behind, physics runs on without waiting
    assert pace.wait(3.0, lambda: True, sleep=wall.sleep, clock=wall) == 0.0
    assert pace.behind(4.0) == {}
    # once it catches up it is waited for again
    pace.heard("est", 3.95)
    assert pace.behind(4.0) == {}
    assert pace.behind(4.2) == {"est": pytest.approx(0.25)}


def test_stopping_the_emulator_ends_a_wait_at_once():
    pace, wall = ConsumerPace(max_lag_s=0.1, max_wait_s=2.0), FakeWall()
    pace.heard("est", 0.0)
    running = iter([True, True, False])
    waited = pace.wait(1.0, lambda: next(running), sleep=wall.sleep, clock=wall, poll_s=0.01)
    assert waited == pytest.approx(0.02) and pace.gave_up == 0


def test_forget_drops_every_consumer():
    pace = ConsumerPace(max_lag_s=0.1)
    pace.heard("est", 0.0)
    pace.forget()
    assert pace.behind(10.0) == {}
