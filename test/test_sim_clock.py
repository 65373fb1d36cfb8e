"""ClockRate: the sim clock's speed against the wall clock, for margins meant in wall time."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.runtime.sim_clock import STILL_BAND_M, ClockRate, HeldFor, StillFor


@pytest.mark.parametrize("factor", [0.5, 1.0, 3.0, 7.25])
def test_rate_of_a_clock_running_at_a_constant_factor(factor):
    rate = ClockRate(window_s=2.0)
    for k in range(300):  # 3 s of wall time at 10 ms
        wall = 100.0 + 0.01 * k
        rate.add(wall, 5.0 + factor * 0.01 * k)
    assert rate.rate() == pytest.approx(factor, rel=1e-9)
    assert rate.wall_margin(1.0) == pytest.approx(max(1.0, factor), abs=0.01)
    assert rate.wall_margin(1.0) >= max(1.0, factor) - 1e-9


def test_unknown_rate_is_real_time_and_a_restarted_clock_starts_over():
    rate = ClockRate(min_span_s=0.3)
    assert rate.rate() == 1.0
    rate.add(0.0, 10.0)
    rate.add(0.1, 10.5)  # 5x, but over less than min_span_s
    assert rate.rate() == 1.0
    for k in range(2, 60):
        rate.add(0.1 * k, 10.0 + 5 * 0.1 * k)
    assert rate.rate() == pytest.approx(5.0)
    rate.add(6.0, 0.0)  # the simulation restarted: sim time went back
    rate.add(6.5, 0.5)
    assert rate.rate() == pytest.approx(1.0)


def test_window_follows_a_change_of_speed():
    rate = ClockRate(window_s=1.0)
    sim = 0.0
    for k in range(200):
        sim += 0.01 * (1.0 if k < 100 else 4.0)
        rate.add(0.01 * k, sim)
    assert rate.rate() == pytest.approx(4.0, rel=0.02)


def test_a_jump_of_the_clock_does_not_count():
    """The first /clock after 0 (a jump to 100 s) or a skipped stretch: one interval, not the rate."""
    rate = ClockRate()
    rate.add(0.0, 0.0)  # not running yet: ignored
    for k in range(1, 40):
        sim = 100.0 + 0.05 * k + (30.0 if k > 20 else 0.0)  # real time, with a 30 s jump
        rate.add(0.05 * k, sim)
    assert rate.rate() == pytest.approx(1.0)


def test_held_for_needs_an_unbroken_stretch_of_sim_time():
    held = HeldFor(0.5)
    assert not held.update(True, 0.0)  # from sim time 0 (not mistaken for "not yet")
    assert not held.update(True, 0.4)
    assert not held.update(False, 0.45)  # a break starts it over
    assert not held.update(True, 0.5)
    assert not held.update(True, 0.99)
    assert held.update(True, 1.0)


def test_still_for_accepts_sensor_jitter_inside_the_band_and_restarts_on_a_move():
    """A pose dithering by a tenth of the band for the whole stretch is at rest; a step of twice the band
    restarts the stretch from the new place."""
    still = StillFor(0.5)
    rng = np.random.default_rng(3)
    rest = np.array([0.01, -0.02, 0.2, 0.001, 0.002, 0.003])
    times = np.arange(0.0, 0.5 + 1e-9, 0.002)
    answers = [still.update(rest + rng.uniform(-0.1, 0.1, 6) * STILL_BAND_M, t) for t in times]
    assert not any(answers[:-1]) and answers[-1]
    moved = rest + np.r_[2 * STILL_BAND_M, 0, 0, 0, 0, 0]
    assert not still.update(moved, 0.6)
    assert not still.update(moved, 1.09)
    assert still.update(moved, 1.1)
    assert np.array_equal(still.anchor, moved)


def test_still_for_sees_a_slow_creep_that_never_jumps():
    """Steps each far inside the band add up: a creep of a band per 0.2 s is never at rest."""
    still = StillFor(0.5)
    times = np.arange(0.0, 3.0, 0.002)
    creep = times / 0.2 * STILL_BAND_M
    assert not any(still.update(np.r_[c, 0, 0, 0, 0, 0], t) for c, t in zip(creep, times))
