"""Every stop stays inside every limit: the e-stop near the stroke end, lifecycle deactivate, reset during an
e-stop's braking, shutdown, the vibration watchdog and the vibration e-stop at 49 Hz / 0.9 g with a 5 ms ramp
-- on the commanded references (sampled densely and on the physics step grid) and, stepped in MuJoCo, on
the states the emulator publishes. Commands that would leave no room to stop are refused."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.emulation.emulator import HardwareEmulator
from stewart_vibration.emulation.safety_controller import SafetyController
from stewart_vibration.emulation.strut_stop import STOP_RESERVE_S
from stewart_vibration.emulation.strut_trajectory import build_trajectory
from stewart_vibration.emulation.vibration_status import CAUSE_OF, DEACTIVATED, EMERGENCY_STOP, SHUTDOWN
from stewart_vibration.errors import ActuatorLimitError
from stewart_vibration.estimation import ForceEstimator
from stewart_vibration.motion.profiles import minimum_jerk, minimum_jerk_duration
from stewart_vibration.robot import LEG_NAMES, VIB_NAMES
from stewart_vibration.sim.mjcf import load_simulation_settings
from stewart_vibration.splines import smoothstep, smoothstep_integral
from stewart_vibration.vibration.waveform import displacement_from_acceleration, fade_out, product_rule, sinusoid

DT = 1 / 2000  # physics step (s)
PERIOD = 0.002  # state period (s)
REL = 1e-3  # commanded references between the checkers' samples: relative allowance
# the simulated struts follow their references through a 10 Hz servo with a feedforward: what the measured
# (published) strut velocities may add to the commanded acceleration, m/s^2 (measured: < 0.01)
SERVO_ACCEL = 0.02
SERVO_STROKE = 1e-6  # m: measured strut length beyond the commanded one


def controller(robot, ramp_s=0.05, watchdog_s=0.5):
    return SafetyController(robot, DT, watchdog_s=watchdog_s, vibration_ramp_s=ramp_s)


def emulator(robot, ramp_s=0.05):
    return HardwareEmulator(robot, load_simulation_settings(timestep=DT), vibration_ramp_s=ramp_s)


def assert_struts_within_limits(robot, follower, t0, t1):
    """The commanded struts from t0 to t1 (s): every 0.5 ms and on the physics step grid (second differences:
    what the servo references are built from) within the stroke, velocity and acceleration limits."""
    lim = robot.limits
    t = np.arange(t0, t1, 5e-4)
    p, v, a = follower.sample(t)
    assert p.min() >= lim.stroke_min - 1e-12 and p.max() <= lim.stroke_max + 1e-12, (p.min(), p.max())
    assert np.abs(v).max() <= lim.strut_velocity_max * (1 + REL)
    assert np.abs(a).max() <= lim.strut_acceleration_max * (1 + REL), np.abs(a).max()
    steps = follower.sample(np.arange(t0, t1, DT))[0]
    assert np.abs(np.diff(steps, 2, axis=0)).max() / DT**2 <= lim.strut_acceleration_max * (1 + REL)
    return p, v, a


def assert_measured_within_limits(robot, rows):
    """Published states [(time, strut positions (6,), strut velocities (6,))]: stroke, velocity, and acceleration
    from the 500 Hz velocities, within the limits plus the servo allowances."""
    lim = robot.limits
    t = np.array([r[0] for r in rows])
    p = np.array([r[1] for r in rows])
    v = np.array([r[2] for r in rows])
    assert np.isfinite(p).all() and np.isfinite(v).all() and (np.diff(t) > 0).all()
    assert p.max() <= lim.stroke_max + SERVO_STROKE and p.min() >= lim.stroke_min - SERVO_STROKE
    assert np.abs(v).max() <= lim.strut_velocity_max * (1 + REL) + 1e-4
    accel = np.abs(np.diff(v, axis=0)).max() / PERIOD
    assert accel <= lim.strut_acceleration_max + SERVO_ACCEL, accel


def run(emu, until, rows=None):
    """Step the emulator to ``until`` (s), recording (time, strut positions, strut velocities)."""
    while emu.time < until - 1e-12:
        emu.advance(PERIOD)
        if rows is not None:
            _, pos, vel, _ = emu.joint_state()
            rows.append((emu.time, pos[:6].copy(), vel[:6].copy()))
    return rows


def smooth_profile(start: float, pieces, step: float = 0.01):
    """One strut's (times [n], positions, velocities, accelerations [n]) from ``start`` (m): ``pieces`` of
    (duration s, velocity at its end m/s), each a smoothstep change of the velocity from the previous piece's
    (0 at first); points every ``step`` s. Positions in closed form (the smoothstep's integral)."""
    total = sum(d for d, _ in pieces)
    t = np.append(np.arange(step, total - 0.5 * step, step), total)  # the last point at the end, at rest
    pos, vel, acc = np.full(t.size, start), np.zeros(t.size), np.zeros(t.size)
    t0, v0 = 0.0, 0.0
    for duration, v1 in pieces:  # each piece adds (v1 - v0) s((t - t0) / duration) to the velocity
        x = (t - t0) / duration
        s, ds, _ = smoothstep(x)
        vel += (v1 - v0) * s
        acc += (v1 - v0) * ds / duration
        pos += (v1 - v0) * duration * smoothstep_integral(x)
        t0, v0 = t0 + duration, v1
    return t, pos, vel, acc


def stroke_end_approach(robot, start_lengths, margin=1e-4, cruise=0.02, ramp=0.4):
    """Every strut from ``start_lengths`` up to stroke_max - ``margin`` (m): a smoothstep ramp to ``cruise`` (m/s)
    over ``ramp`` s, cruise, and a smoothstep braking over ``ramp`` s (4 mm at 20 mm/s) ending there; the
    struts in proportion. Returns (times, positions, velocities, accelerations [n, 6], braking start)."""
    goal = robot.limits.stroke_max - margin
    travel = goal - start_lengths.max()
    cruise_s = (travel - cruise * ramp) / cruise  # the two ramps cover cruise * ramp / 2 each
    t, pos, vel, acc = smooth_profile(0.0, [(ramp, cruise), (cruise_s, cruise), (ramp, 0.0)])
    scale = (goal - start_lengths) / travel
    return t, start_lengths + pos[:, None] * scale, vel[:, None] * scale, acc[:, None] * scale, ramp + cruise_s


@pytest.mark.parametrize("before_braking", [0.6, 0.25, 0.1, 0.02, 0.0, -0.1, -0.3])
def test_an_estop_near_the_stroke_end_stays_inside_the_stroke(robot, before_braking):
    """Braking toward 0.1 mm short of stroke_max, an e-stop just before (or during) the planned braking: the
    stop follows the commanded path, so no strut goes past where the command itself would end (the old quintic
    stop overshot the stroke by up to 0.54 mm)."""
    ctl = controller(robot)
    home = ctl.home_lengths
    t, pos, vel, acc, braking = stroke_end_approach(robot, home)
    ctl.command_struts(0.0, LEG_NAMES, 0.0, t, pos, vel, acc)
    at = braking - before_braking
    ctl.emergency_stop(at)
    stop = ctl.struts.stop
    assert stop is not None and stop.at == at
    p, v, a = assert_struts_within_limits(robot, ctl.struts, at - 0.05, at + stop.duration + 0.5)
    assert p.max() <= robot.limits.stroke_max - 1e-4 + 1e-12  # never past the command's own end
    assert np.abs(v[-1]).max() == 0.0


def test_an_estop_near_the_stroke_end_in_mujoco(robot):
    """The same stop (e-stop 20 ms before the planned braking) stepped in MuJoCo: the published strut lengths
    stay within the stroke, their acceleration within the limit (plus the servo allowance)."""
    emu = emulator(robot)
    t, pos, vel, acc, braking = stroke_end_approach(robot, emu.home_lengths)
    emu.command_struts(LEG_NAMES, 0.0, t, pos, vel, acc)
    rows = run(emu, braking - 0.02, [])
    emu.emergency_stop()
    run(emu, braking + 1.5, rows)
    assert emu.fault is None
    assert_measured_within_limits(robot, rows)
    assert max(r[1].max() for r in rows) <= robot.limits.stroke_max - 1e-4 + SERVO_STROKE


def fast_move(robot, home, delta=0.01, speed=0.9):
    goal = home + np.array([delta, -delta, delta, -delta, delta, -delta])
    duration = minimum_jerk_duration(home, goal, speed * robot.limits.strut_velocity_max, 0.5)
    times = np.linspace(duration / 40, duration, 40)
    return duration, times, minimum_jerk(home, goal, duration, times)


def test_deactivate_mid_move_brakes_within_the_acceleration_limit(robot):
    """Lifecycle deactivate during a move at 90 % of the strut speed (it used to hold the position at once: a
    velocity step, 1.4 m/s^2): the struts brake to rest along the path within the acceleration limit."""
    emu = emulator(robot)
    duration, times, (pos, vel, acc) = fast_move(robot, emu.home_lengths)
    emu.command_struts(LEG_NAMES, 0.0, times, pos, vel, acc)
    rows = run(emu, 0.45 * duration, [])
    at = emu.time
    speed = np.abs(emu.struts.sample([at])[1]).max()
    assert speed > 0.8 * robot.limits.strut_velocity_max
    emu.halt(DEACTIVATED)
    assert not emu.estopped and emu.struts.stop is not None
    assert_struts_within_limits(robot, emu.struts, at - 0.01, at + 3.0)
    run(emu, at + emu.struts.stop.duration + 0.5, rows)
    assert_measured_within_limits(robot, rows)
    assert np.abs(rows[-1][2]).max() < 1e-5  # at rest
    # the stop ended on the commanded path: where the move itself passed
    original = minimum_jerk(emu.home_lengths, pos[-1], duration, np.linspace(0, duration, 20001))[0]
    assert np.abs(original - emu.struts.sample([emu.time])[0][0]).max(axis=1).min() < 2e-6


def test_reset_during_the_estop_braking_plans_from_the_commanded_state(robot):
    """Reset 0.1 s into the e-stop's braking (it used to hold the position there: a velocity step): the way
    home starts where the stop comes to rest, when it does -- no step in velocity, every limit kept."""
    emu = emulator(robot)
    duration, times, (pos, vel, acc) = fast_move(robot, emu.home_lengths)
    emu.command_struts(LEG_NAMES, 0.0, times, pos, vel, acc)
    rows = run(emu, 0.5 * duration, [])
    emu.emergency_stop()
    stop = emu.struts.stop
    run(emu, stop.at + 0.1, rows)
    now = emu.time
    assert now < stop.end  # still braking
    before = emu.struts.sample([now])
    until_home = emu.reset()
    after = emu.struts.sample([now])
    assert np.abs(after[0] - before[0]).max() < 1e-12 and np.abs(after[1] - before[1]).max() < 1e-12
    assert not emu.estopped and until_home > stop.end - now
    assert_struts_within_limits(robot, emu.struts, now - 0.01, now + until_home + 0.5)
    run(emu, now + until_home + 0.3, rows)
    assert_measured_within_limits(robot, rows)
    assert np.abs(rows[-1][1] - emu.home_lengths).max() < 1e-5


def test_shutdown_brakes_to_rest_and_says_when_it_is_at_rest(robot):
    """The stop before physics ends (the node waits for ``at_rest``): struts and vibration at rest after the stop
    and the ramp, within every limit, and only then."""
    ctl = controller(robot)
    duration, times, (pos, vel, acc) = fast_move(robot, ctl.home_lengths)
    ctl.command_struts(0.0, LEG_NAMES, 0.0, times, pos, vel, acc)
    window = vibration_window(49.0, 0.9, 3.0)
    ctl.command_vibration(0.0, VIB_NAMES, 0.2, *window)
    at = 0.5 * duration
    assert not ctl.at_rest(at)
    ctl.halt(at, SHUTDOWN)
    end = max(ctl.struts.stop.end, ctl.vibration.commanded_until())
    assert not ctl.at_rest(end - 1e-3) and ctl.at_rest(end)
    assert_struts_within_limits(robot, ctl.struts, at, end + 0.1)
    assert_vibration_within_limits(robot, ctl.vibration, at - 0.01, end + 0.1)


def vibration_window(frequency, accel_g, duration, ramp=0.2, end_moving=False, phase=0.3):
    """(times, positions, velocities, accelerations) of a ramped sinusoid on every unit at ``frequency`` (Hz),
    ``accel_g`` (g), samples 0.25 ms apart; with ``end_moving`` it stops mid-vibration at the zero crossing
    nearest ``duration`` (no ramp-out: the units brake past it and the watchdog must act)."""
    amp = displacement_from_acceleration(accel_g, frequency)
    omega = 2 * np.pi * frequency
    if end_moving:
        duration = (np.round((omega * duration + phase) / np.pi) * np.pi - phase) / omega
    t = np.linspace(0.0, duration, int(round(duration / 2.5e-4)) + 1)
    if end_moving:
        g, dg, ddg = smoothstep(t / ramp)
        p, v, a = product_rule(sinusoid(t, amp, frequency, phase), (g, dg / ramp, ddg / ramp**2))
    else:
        p, v, a = sinusoid(t, amp, frequency, phase, duration=duration, ramp_time=ramp)
    return (t, *(np.tile(np.asarray(x)[:, None], 6) for x in (p, v, a)))


def assert_vibration_within_limits(robot, buffer, t0, t1):
    unit = robot.vibration_unit
    t = np.arange(t0, t1, 2e-5)
    p, v, a = buffer.sample(t)
    assert np.abs(p).max() <= unit.amplitude_max * (1 + REL)
    assert np.abs(v).max() <= unit.velocity_max * (1 + REL)
    assert np.abs(a).max() <= unit.acceleration_max * (1 + REL), np.abs(a).max() / 9.80665
    return p, v, a


def test_the_watchdog_ramp_stays_within_the_unit_limits_whatever_the_ramp_parameter(robot):
    """A 49 Hz / 0.9 g window that ends mid-vibration and nothing after it: the watchdog ramps it out -- over
    more than the 5 ms vibration_ramp_s, as much as the unit's 1 g needs."""
    ctl = controller(robot, ramp_s=0.005, watchdog_s=0.1)
    window = vibration_window(49.0, 0.9, 1.0, end_moving=True)
    ctl.command_vibration(0.0, VIB_NAMES, 0.1, *window)
    start, reason = ctl.vibration.ramp()
    assert start is not None and "watchdog" in reason
    assert ctl.vibration.ramp_duration(start) > 0.005
    assert_vibration_within_limits(robot, ctl.vibration, 0.05, start + 2.5)
    assert np.abs(ctl.vibration.sample([start + ctl.vibration.ramp_duration(start)])[0]).max() == 0.0


def test_a_vibration_estop_at_49_hz_and_09_g_stays_within_1_g(robot):
    """The e-stop during a 49 Hz / 0.9 g vibration with vibration_ramp_s 0.005 (it measured 11.8-13.9 m/s^2):
    the ramp stretches until the faded command stays within 1 g; the published vib_i positions agree."""
    emu = emulator(robot, ramp_s=0.005)
    window = vibration_window(49.0, 0.9, 3.0)
    emu.command_vibration(VIB_NAMES, 0.2, *window)
    run(emu, 1.0137)
    at = emu.time
    emu.emergency_stop()
    ramp = emu.vibration.ramp_duration(at)
    assert ramp > 0.005
    assert_vibration_within_limits(robot, emu.vibration, at - 0.05, at + ramp + 0.05)
    # the unstretched 5 ms fade of the same command: beyond 1 g (what the stretch prevents)
    t = np.arange(at, at + 0.005, 2e-5)
    raw = emu.vibration._unfaded(t)
    _, _, fixed = product_rule(raw, tuple(x[:, None] for x in fade_out(t, at, 0.005)))
    assert np.abs(fixed).max() > robot.vibration_unit.acceleration_max
    published = []
    while emu.time < at + ramp + 0.05:
        emu.advance(PERIOD)
        published.append(emu.joint_state()[1][6:])
    published = np.array(published)
    second = np.abs(np.diff(published, 2, axis=0)).max() / PERIOD**2  # 500 Hz: under-reads 49 Hz by 3 %
    assert second <= robot.vibration_unit.acceleration_max * (1 + REL)
    assert np.abs(published[-1]).max() == 0.0


def test_the_estimator_mirrors_the_stretched_ramps_and_the_strut_stops(robot):
    """The estimator's copy of the commands (the same classes): the same stretched vibration ramp and the same
    strut stop for an e-stop and for deactivate."""
    for reason in (EMERGENCY_STOP, DEACTIVATED):
        ctl = controller(robot, ramp_s=0.005)
        estimator = ForceEstimator(robot, vibration_ramp_s=0.005)
        duration, times, (pos, vel, acc) = fast_move(robot, ctl.home_lengths)
        ctl.command_struts(0.0, LEG_NAMES, 0.0, times, pos, vel, acc)
        zeros = np.zeros((1, 6))
        estimator.estimate([0.0], ctl.home_lengths[None, :], zeros, zeros, zeros)
        estimator.command_struts(build_trajectory(LEG_NAMES, LEG_NAMES, 0.0, times, pos, vel, acc), now=0.0)
        window = vibration_window(49.0, 0.9, 3.0)
        ctl.command_vibration(0.0, VIB_NAMES, 0.2, *window)
        estimator.command_vibration(build_trajectory(VIB_NAMES, VIB_NAMES, 0.2, *window), now=0.0)
        at = 0.4 * duration
        ctl.halt(at, reason)
        estimator.apply_ramp(at, reason, CAUSE_OF[reason])
        t = np.arange(at - 0.01, at + 2.5, 1e-3)
        for ours, theirs in zip(estimator.struts.sample(t), ctl.struts.sample(t), strict=True):
            assert np.abs(ours - theirs).max() < 1e-12
        for ours, theirs in zip(estimator.vibration.sample(t), ctl.vibration.sample(t), strict=True):
            assert np.abs(ours - theirs).max() < 1e-12


def test_commands_that_leave_no_room_to_stop_are_refused(robot):
    """A strut braking from full speed at 94 % of the acceleration limit (at half speed when it brakes hardest)
    more than STOP_RESERVE_S before the command ends: no stop within the limit exists while it brakes --
    refused (stop_reserve) with the time; the same braking as the command's end (its own stop) is taken."""
    ctl = controller(robot)
    v_max = robot.limits.strut_velocity_max
    brake = [(0.4, v_max), (0.5, v_max), (0.4, 0.0)]  # the hardest braking at t = 1.1 s
    for tail, refused in (([(0.5, 0.0), (3.0, -0.002), (3.0, 0.0)], True), ([], False)):
        t, p, v, a = smooth_profile(ctl.home_lengths[0], brake + tail)
        assert np.abs(a).max() <= robot.limits.strut_acceleration_max
        table = [np.tile(x[:, None], 6) for x in (p, v, a)]
        if refused:
            with pytest.raises(ActuatorLimitError) as error:
                ctl.command_struts(0.0, LEG_NAMES, 0.0, t, *table)
            assert error.value.limit_name == "stop_reserve" and 0.9 < error.value.time < 1.3
            assert t[-1] - error.value.time > STOP_RESERVE_S
        else:
            ctl.command_struts(0.0, LEG_NAMES, 0.0, t, *table)


def safety_stop(ctl, at, reason):
    if reason == EMERGENCY_STOP:
        ctl.emergency_stop(at)
    else:
        ctl.halt(at, reason)


def test_a_stop_during_a_stop_keeps_the_first_and_every_limit(robot):
    """Deactivate during an e-stop's braking, an e-stop during deactivate's, a second halt: the stop under way
    goes on unchanged (it already keeps every limit); the struts come to rest once."""
    for first, second in ((EMERGENCY_STOP, DEACTIVATED), (DEACTIVATED, EMERGENCY_STOP), (SHUTDOWN, SHUTDOWN)):
        ctl = controller(robot)
        duration, times, (pos, vel, acc) = fast_move(robot, ctl.home_lengths)
        ctl.command_struts(0.0, LEG_NAMES, 0.0, times, pos, vel, acc)
        at = 0.5 * duration
        safety_stop(ctl, at, first)
        stop = ctl.struts.stop
        t = np.arange(at, at + 1.0, 1e-3)
        before = ctl.struts.sample(t)
        safety_stop(ctl, at + 0.1, second)
        assert ctl.struts.stop == stop
        after = ctl.struts.sample(t)
        assert all(np.array_equal(a, b) for a, b in zip(before, after, strict=True))
        assert_struts_within_limits(robot, ctl.struts, at - 0.01, stop.end + 0.2)
