"""The vibration units' command buffer: interpolation, continuous splices, refusals
with reasons, safety ramps without latching, limits of any window, and the status classification.

References are written here: an analytic ramped sine (not the library's waveform) sampled into windows.
"""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration import VibrationLimitError
from stewart_vibration.emulation.strut_trajectory import build_trajectory
from stewart_vibration.emulation.vibration_buffer import VibrationBuffer

VIB = [f"vib_{i}" for i in range(1, 7)]
GAINS = np.array([0.9, -0.7, 0.95, 0.88, -0.83, 0.94])
F, A, RAMP = 35.0, 60e-6, 0.1  # Hz, m, s (quintic smoothstep ramps)
W = 2 * np.pi * F


def smooth(x):
    """Quintic smoothstep s, s', s'' on x clipped to [0, 1]."""
    x = np.clip(x, 0.0, 1.0)
    return 10 * x**3 - 15 * x**4 + 6 * x**5, 30 * x**2 * (1 - x) ** 2, 60 * x * (1 - x) * (1 - 2 * x)


def signal(t, amp=A, tail=None):
    """(p, v, a) [n, 6]: amp * e(t) * gains * sin(w t), e ramping in over [0, RAMP] and, with ``tail``,
    out over [tail, tail + RAMP]."""
    t = np.asarray(t, dtype=float)
    s, ds, dds = smooth(t / RAMP)
    e, de, dde = s, ds / RAMP, dds / RAMP**2
    if tail is not None:
        g, dg, ddg = smooth((tail + RAMP - t) / RAMP)
        dg, ddg = -dg / RAMP, ddg / RAMP**2
        e, de, dde = e * g, de * g + e * dg, dde * g + 2 * de * dg + e * ddg
    sn, cs = np.sin(W * t), np.cos(W * t)
    x = amp * e * sn
    xd = amp * (de * sn + e * W * cs)
    xdd = amp * (dde * sn + 2 * de * W * cs - e * W * W * sn)
    return x[:, None] * GAINS, xd[:, None] * GAINS, xdd[:, None] * GAINS


def window(stamp, t0, t1, amp=A, tail=None, accelerations=True, dt=1e-3):
    """A window of ``signal`` on the grid [t0, t1] (s from the stamp)."""
    t = np.arange(round(t0 / dt), round(t1 / dt) + 1) * dt
    p, v, a = signal(t, amp, tail)
    return build_trajectory(VIB, VIB, stamp, t, p, v, a if accelerations else None)


@pytest.fixture
def buffer(robot):
    return VibrationBuffer(robot.vibration_unit, watchdog_s=0.5, ramp_s=0.05)


def test_quintic_and_cubic_interpolation_reproduce_the_signal(buffer, robot):
    buffer.add(window(10.0, 0.0, 0.6, tail=0.5), now=9.9)
    t = np.linspace(10.0, 10.6, 2777)
    pos, vel, acc = buffer.sample(t)
    exact = signal(t - 10.0, tail=0.5)
    assert np.abs(pos - exact[0]).max() < 1e-7 * A  # quintic Hermite at 28 samples per period
    assert np.abs(vel - exact[1]).max() < 1e-6 * A * W
    assert np.abs(acc - exact[2]).max() < 1e-4 * A * W * W
    cubic = VibrationBuffer(robot.vibration_unit)
    cubic.add(window(10.0, 0.0, 0.6, tail=0.5, accelerations=False), now=9.9)
    pos, vel, acc = cubic.sample(t)
    assert np.abs(pos - exact[0]).max() < 1e-4 * A
    assert 1e-3 * A * W * W < np.abs(acc - exact[2]).max() < 0.1 * A * W * W  # piecewise-linear acceleration


def test_continuing_window_splices_and_replaces_the_tail(buffer):
    stamp = 100.0
    buffer.add(window(stamp, 0.0, 0.7, tail=0.6), now=stamp - 0.3)
    splice = buffer.add(window(stamp, 0.4, 1.5, tail=1.4), now=stamp + 0.1)  # arrives before its first sample
    assert splice == pytest.approx(stamp + 0.4)
    t = np.arange(stamp, stamp + 1.5, 1e-4)
    pos, vel, acc = buffer.sample(t)
    exact = signal(t - stamp, tail=1.4)  # the first window's tail is gone
    assert np.abs(pos - exact[0]).max() < 1e-7 * A
    assert np.abs(vel - exact[1]).max() < 1e-6 * A * W
    # a late window (first sample already past) splices at "now" where both agree
    buffer.add(window(stamp, 0.9, 2.5, tail=2.4), now=stamp + 1.0)
    t = np.arange(stamp + 0.95, stamp + 2.5, 1e-4)
    assert np.abs(buffer.sample(t)[0] - signal(t - stamp, tail=2.4)[0]).max() < 1e-7 * A


def test_discontinuous_splice_is_refused_with_the_reason_and_changes_nothing(buffer):
    stamp = 50.0
    buffer.add(window(stamp, 0.0, 0.8, tail=0.7), now=stamp - 0.2)
    t = np.linspace(stamp, stamp + 0.9, 500)
    before = buffer.sample(t)
    with pytest.raises(VibrationLimitError) as err:
        buffer.add(window(stamp, 0.3, 1.2, amp=A / 2, tail=1.1), now=stamp + 0.1)
    assert err.value.limit_name == "splice" and "discontinuous splice" in str(err.value) and "vib_" in str(err.value)
    after = buffer.sample(t)
    assert all(np.array_equal(x, y) for x, y in zip(before, after, strict=True))


def test_first_window_arriving_after_its_start_is_refused(buffer):
    with pytest.raises(VibrationLimitError) as err:
        buffer.add(window(20.0, 0.0, 1.0, tail=0.9), now=20.15)  # idle units; the window is mid ramp-in now
    assert err.value.limit_name == "splice" and "0.150 s after its first sample" in str(err.value)
    assert not buffer.times.size


def test_window_ending_at_rest_runs_out_smoothly_without_a_watchdog(buffer):
    stamp = 5.0
    buffer.add(window(stamp, 0.0, 0.5, tail=0.4), now=stamp - 0.2)
    assert buffer.ramp() == (None, "")  # ends at rest: no safety ramp needed
    t = np.arange(stamp, stamp + 1.5, 1e-4)
    pos, vel, _ = buffer.sample(t)
    assert np.abs(pos[t > stamp + 0.5]).max() == 0.0
    assert np.abs(np.diff(pos, axis=0)).max() < 1.01 * A * W * 1e-4  # no step anywhere
    status = buffer.status(stamp + 1.0)
    assert status.state == "idle" and status.ramp_start is None


def test_window_ending_away_from_rest_is_ramped_out_by_the_watchdog(buffer, robot):
    stamp, now = 5.0, 4.8
    buffer.add(window(stamp, 0.0, 0.3), now=now)  # steady amplitude at its end: not at rest
    start, reason = buffer.ramp()
    assert start == pytest.approx(max(stamp + 0.3, now + 0.5)) and "watchdog" in reason
    assert buffer.status(stamp + 0.1).ramp_cause == "watchdog"  # typed: readers never parse the reason
    t = np.arange(stamp, stamp + 1.0, 1e-4)
    pos, vel, _ = buffer.sample(t)
    assert np.abs(pos[t >= start + buffer.ramp_s + 1e-9]).max() == 0.0  # at rest ramp_s after the ramp start
    assert buffer.ramp_s <= 0.1
    steps = np.abs(np.diff(pos, axis=0)).max()
    assert steps < 1.01 * robot.vibration_unit.velocity_max * 1e-4  # bounded velocity: no step
    assert np.abs(vel).max() <= A * W * 1.5


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_tail_inside_the_rest_band_that_brakes_out_of_it_is_ramped_out(buffer, robot, sign):
    """A window ending just inside the rest band (position and velocity below rest_position / rest_velocity)
    but moving outwards: the braking past its end carries the units v * tau further (tau >= 0.1 ms), out of
    the band (hypothesis beside CI: 1.0038e-7 m against 1e-7). The settled position counts: the watchdog ramps
    it out, and the units end at rest. Written by hand: a two-point window, cubic, no library waveform."""
    stamp = 5.0
    p_end, v_end = 0.99 * buffer.rest_position * sign, 0.99 * buffer.rest_velocity * sign
    times = np.array([0.0, 0.01])
    pos = np.zeros((2, 6))
    vel = np.zeros((2, 6))
    pos[1, 2], vel[1, 2] = p_end, v_end
    buffer.add(build_trajectory(VIB, VIB, stamp, times, pos, vel, None), now=stamp - 0.1)
    braked = p_end + v_end * max(abs(v_end) / robot.vibration_unit.acceleration_max, 1e-4)  # where braking holds it
    assert abs(braked) > buffer.rest_position  # the case: braking leaves the band
    start, reason = buffer.ramp()
    assert start is not None and "watchdog" in reason
    late = buffer.sample([buffer.commanded_until() + 0.01, stamp + 5.0])[0]
    assert np.abs(late).max() <= buffer.rest_position * 1e-6


def test_no_latch_a_new_vibration_starts_after_any_ramp_out(buffer):
    buffer.add(window(5.0, 0.0, 0.3), now=4.8)  # ends away from rest -> watchdog ramp (see above)
    buffer.add(window(8.0, 0.0, 0.5, tail=0.4), now=7.5)  # from rest, later: accepted, no reset needed
    t = np.arange(8.0, 8.5, 1e-4)
    assert np.abs(buffer.sample(t)[0] - signal(t - 8.0, tail=0.4)[0]).max() < 1e-7 * A
    buffer.stop(8.45, "emergency stop", "emergency_stop")  # an explicit ramp (as the e-stop), then again from rest
    buffer.add(window(9.0, 0.0, 0.5, tail=0.4), now=8.8)
    assert buffer.ramp() == (None, "")
    assert np.abs(buffer.sample([9.25])[0]).max() > 0.5 * A * 0.7


@pytest.mark.parametrize("ahead_s", [0.3, 1.5, 4.0])
def test_a_window_queued_far_ahead_leaves_the_running_one_alone_until_it_starts(buffer, ahead_s):
    """A vibration from rest to rest, and during it the next one queued ``ahead_s`` after it ends (longer than
    the history the buffer keeps, too): the running one plays out unchanged, then the queued one."""
    buffer.add(window(10.0, 0.0, 0.6, tail=0.5), now=9.9)
    later = 10.6 + ahead_s
    buffer.add(window(later, 0.0, 0.6, tail=0.5), now=10.2)
    t = np.arange(10.2, 10.6, 1e-4)
    assert np.abs(buffer.sample(t)[0] - signal(t - 10.0, tail=0.5)[0]).max() < 1e-7 * A
    t = np.arange(later, later + 0.6, 1e-4)
    assert np.abs(buffer.sample(t)[0] - signal(t - later, tail=0.5)[0]).max() < 1e-7 * A
    assert np.abs(buffer.sample(np.arange(10.61, later, 1e-3))[0]).max() < 1e-9  # at rest between


def test_window_while_a_safety_ramp_runs_is_refused(buffer):
    buffer.add(window(5.0, 0.0, 1.0, tail=0.9), now=4.9)
    buffer.stop(5.3, "emergency stop", "emergency_stop")
    with pytest.raises(VibrationLimitError) as err:
        buffer.add(window(5.0, 0.4, 1.5, tail=1.4), now=5.32)  # mid ramp: its full amplitude does not match
    assert err.value.limit_name == "splice"


@pytest.mark.parametrize("times,positions,velocities,limit", [
    ([0.0, 0.01], [0.0, 2e-4], [0.0, 0.0], "amplitude_max"),  # from rest to 200 um: beyond the unit's 100 um
    ([0.0, 0.001, 0.002], [0.0, 0.0, 1e-4], None, "velocity_max"),  # implied end velocity 0.1 m/s > 0.05
    ([0.0, 0.002, 0.004], [0.0, 3e-5, 5e-5], [0.0, 0.06, 0.0], "velocity_max"),  # a given knot velocity
    ([0.0, 0.002], [0.0, 2e-5], [0.0, 0.0], "acceleration_max"),  # cubic from rest: 6 dp / h^2 = 30 m/s^2
    ([0.0], [5e-5], None, "splice"),  # one point away from rest: a step from the idle units
])
def test_short_windows_are_checked(buffer, times, positions, velocities, limit):
    pos = np.zeros((len(times), 6))
    pos[:, 2] = positions
    vel = None
    if velocities is not None:
        vel = np.zeros((len(times), 6))
        vel[:, 2] = velocities
    with pytest.raises(VibrationLimitError) as err:
        buffer.add(build_trajectory(VIB, VIB, 30.0, times, pos, vel), now=29.5)
    assert err.value.limit_name == limit and err.value.leg == 3, str(err.value)


def test_accepted_random_windows_never_exceed_a_limit(robot):
    """Random short windows (1-6 points, with and without velocities/accelerations): whatever is accepted,
    its densely sampled output stays within the unit's limits (the property the emulator relies on)."""
    rng = np.random.default_rng(7)
    unit = robot.vibration_unit
    accepted = 0
    for _ in range(400):
        buf = VibrationBuffer(unit, watchdog_s=0.5, ramp_s=0.05)
        n = int(rng.integers(1, 7))
        times = np.cumsum(rng.uniform(0.0005, 0.05, n))
        pos = rng.normal(0, 30e-6, (n, 6)) * rng.uniform(0, 1, (n, 1))
        pos[0] = 0.0  # from rest, so the splice can succeed
        vel = rng.normal(0, 5e-3, (n, 6)) if rng.random() < 0.7 else None
        if vel is not None:
            vel[0] = 0.0
        acc = rng.normal(0, 2.0, (n, 6)) if vel is not None and rng.random() < 0.5 else None
        try:
            buf.add(build_trajectory(VIB, VIB, 1.0, times, pos, vel, acc), now=0.9)
        except VibrationLimitError:
            continue
        accepted += 1
        t = np.linspace(0.9, 1.0 + times[-1] + 1.0, 20000)
        p, v, a = buf.sample(t)
        assert np.abs(p).max() <= unit.amplitude_max * 1.001
        assert np.abs(v).max() <= unit.velocity_max * 1.001
        inside = t <= 1.0 + times[-1]  # the spline the window commands (the watchdog ramp after it is checked
        assert np.abs(a[inside]).max() <= unit.acceleration_max * 1.001  # by the ramp tests above)
    assert accepted > 40


def test_max_lookahead(buffer):
    buffer.max_lookahead_s = 2.0
    with pytest.raises(VibrationLimitError) as err:
        buffer.add(window(10.0, 0.0, 3.0, tail=2.9), now=9.5)
    assert err.value.limit_name == "max_lookahead_s"


def test_status_follows_the_vibration(buffer):
    stamp = 10.0
    buffer.add(window(stamp, 0.0, 1.2, tail=1.0), now=9.0)
    states = {t: buffer.status(stamp + t).state for t in (-0.5, 0.05, 0.5, 1.05, 1.5)}
    assert states == {-0.5: "pending", 0.05: "ramping_in", 0.5: "running", 1.05: "ramping_out", 1.5: "idle"}
    long_after = buffer.status(stamp + 10.0)  # no sample within the span on either side
    assert long_after.state == "idle" and not long_after.amplitude.any()
    amplitude = buffer.status(stamp + 0.5).amplitude
    np.testing.assert_allclose(amplitude, A * np.abs(GAINS), rtol=0.02)
    buffer.stop(stamp + 0.6, "emergency stop", "emergency_stop")
    status = buffer.status(stamp + 0.62)
    assert status.state == "ramping_out" and status.ramp_reason == "emergency stop"
    assert status.ramp_cause == "emergency_stop"
    assert buffer.status(stamp + 0.8).state == "idle"


def test_a_repeated_window_prefix_is_not_checked_twice_but_its_new_tail_is(buffer, robot):
    """A streamed window repeats the buffered samples up to the old tail; only the new part is checked again,
    and a new part beyond the limits is still refused."""
    import stewart_vibration.emulation.vibration_buffer as module

    calls = []
    checker = module.check_command_limits
    buffer.add(window(40.0, 0.0, 1.0, tail=0.8), now=39.5)
    try:
        module.check_command_limits = lambda *args: (calls.append(len(args[1])), checker(*args))[1]
        buffer.add(window(40.0, 0.3, 1.6, tail=1.4), now=40.1)
        assert calls and calls[-1] < 1300 * 0.7  # the 0.5 s repeated prefix (500 knots) is not sampled again
        bad = window(40.0, 0.6, 2.2, tail=2.0)
        t = np.arange(round(0.6 * 1000), round(2.2 * 1000) + 1) / 1000.0
        bad.positions[t > 1.7] *= 4.0  # beyond the amplitude limit after the repeated prefix
        with pytest.raises(VibrationLimitError):
            buffer.add(bad, now=40.4)
    finally:
        module.check_command_limits = checker


@pytest.mark.parametrize("offset", [1.1125369292536007e-308, 1e-15, 5e-10])
def test_a_window_starting_a_hair_after_a_buffered_knot_replaces_it_and_stays_finite(buffer, offset):
    """Windows at rest stamped ``offset`` s after a buffered knot (float rounding of equal stamps, or a sender's
    denormal lead): the knot closer than a nanosecond gives way to the window's first one, so no segment of
    that length (whose spline is 0/0) is ever followed; the commands stay finite and within the limits."""
    buffer.add(window(10.0, 0.0, 0.3), now=10.0)
    buffer.add(window(10.0, 0.0, 0.3), now=10.0)  # the same window again at the same time
    buffer.add(window(10.0 + offset, 0.0, 0.3), now=10.0)
    t = np.linspace(9.99, 10.31, 3201)
    pos, vel, acc = buffer.sample(t)
    assert np.isfinite(pos).all() and np.isfinite(vel).all() and np.isfinite(acc).all()
    expected = signal(t - 10.0 - offset)[0]
    inside = (t >= 10.0 + 1e-3) & (t <= 10.3)
    assert np.abs(pos[inside] - expected[inside]).max() < 1e-9
    assert (np.diff(buffer.times) >= 1e-9).all()
