"""StrutRest judges rest from measured strut lengths alone: a drift above its speed limit is motion, a
vibration (or noise) about a fixed mean is rest, and nothing is at rest until two windows are known."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.motion.strut_rest import REST_SPEED_M_S, REST_WINDOW_S, StrutRest

RATE_HZ = 500.0
HOME = np.full(6, 0.16)


def feed(rest: StrutRest, lengths_of, duration_s: float, t0: float = 0.0, block: int = 10) -> None:
    """Observe ``lengths_of(t)`` [n, 6] at RATE_HZ from t0 for duration_s, in batches of ``block`` states."""
    t = t0 + np.arange(int(round(duration_s * RATE_HZ))) / RATE_HZ
    for start in range(0, len(t), block):
        ts = t[start:start + block]
        rest.observe(ts, lengths_of(ts))


def test_nothing_known_is_not_at_rest():
    rest = StrutRest()
    assert rest.speed() is None and not rest.at_rest()
    feed(rest, lambda t: np.tile(HOME, (len(t), 1)), 1.5 * REST_WINDOW_S)  # less than two windows
    assert rest.speed() is None and not rest.at_rest()


@pytest.mark.parametrize("speed", [0.5 * REST_SPEED_M_S, 2.0 * REST_SPEED_M_S, 5e-3])
def test_a_steady_drift_is_measured_as_its_speed(speed):
    """A strut moving at a constant speed: the drift between the two windows' means is that speed (a ramp's
    mean moves exactly with it), so rest is decided by the limit alone."""
    rest = StrutRest()
    leg = 3
    feed(rest, lambda t: HOME + np.outer(t, np.eye(6)[leg]) * speed, 1.0)
    assert rest.speed() == pytest.approx(speed, rel=0.02)
    assert rest.at_rest() == (speed < REST_SPEED_M_S)


def test_a_vibration_about_a_fixed_mean_is_rest():
    """35 Hz, 60 um on every unit (the planner's slowest therapy frequency) plus encoder-like noise."""
    rng = np.random.default_rng(3)
    rest = StrutRest()
    phases = np.linspace(0, np.pi, 6)
    feed(rest, lambda t: HOME + 60e-6 * np.sin(2 * np.pi * 35.0 * t[:, None] + phases)
         + rng.normal(0, 1e-6, (len(t), 6)), 1.0)
    assert rest.at_rest(), rest.speed()


def test_a_move_that_stops_becomes_rest_after_two_windows():
    """A minimum-jerk-like move of 5 mm over 0.5 s, then still: moving during the move, at rest once both
    windows are after its end, not before."""
    rest = StrutRest()

    def lengths(t):
        s = np.clip(t / 0.5, 0, 1)
        return HOME + (0.005 * (10 * s**3 - 15 * s**4 + 6 * s**5))[:, None] * np.ones(6)

    feed(rest, lengths, 0.4)
    assert not rest.at_rest()
    feed(rest, lengths, 0.5 + 2.5 * REST_WINDOW_S, t0=0.4)
    assert rest.at_rest()


def test_a_clock_that_restarts_forgets_the_old_lengths():
    rest = StrutRest()
    feed(rest, lambda t: np.tile(HOME, (len(t), 1)), 1.0, t0=10.0)
    assert rest.at_rest()
    rest.observe([0.0], [HOME])  # the robot's clock restarted: one state is not two windows
    assert rest.speed() is None and not rest.at_rest()
