"""vibration.demand_schedule with vibration.streaming: a vibration whose leg demands a loop corrects while it
streams. References: the plan's own exact windows (uncorrected), finite differences, and the hardware
emulator's splice checks (SafetyController), which refuse a window that does not continue the one before."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.errors import InvalidInputError, VibrationLimitError
from stewart_vibration.paper import paper_pose
from stewart_vibration.vibration.decompose import decompose_vibration
from stewart_vibration.vibration.demand_schedule import DemandSchedule
from stewart_vibration.vibration.leg_demands import decomposition_demands
from stewart_vibration.vibration.streaming import StreamSettings, VibrationStream

F = 35.0


@pytest.fixture
def plan(robot):
    return decompose_vibration(robot, paper_pose(robot), [0.0, 0.0, 1.0], acceleration_g=0.3, frequency=F)


def streamed(robot, plan, corrections, duration=None):
    """Windows sent every 0.5 s for 3 s; before the window at time T the correction factor ``corrections[T]``
    (complex, on every leg) is scheduled from that window's splice."""
    u0 = decomposition_demands(plan)
    schedule = DemandSchedule(u0, F, blend_s=0.1)
    stream = VibrationStream(robot, plan, StreamSettings(duration=duration), demands=schedule)
    windows = []
    for now in np.arange(0.0, 3.0, 0.5):
        if now in corrections:
            schedule.correct(u0 * corrections[now], stream.splice_time(now))
        window = stream.next_window(now)
        if window is None:
            break
        windows.append(window)
    return windows, schedule


def test_uncorrected_demands_are_the_plans_windows_to_second_order(robot, plan):
    ours, _ = streamed(robot, plan, {})
    exact = VibrationStream(robot, plan, StreamSettings(duration=None))
    for window, now in zip(ours, np.arange(0.0, 3.0, 0.5)):
        theirs = exact.next_window(now)
        np.testing.assert_array_equal(window.times, theirs.times)
        # the plan's exact IK signals differ by the legs' curvature terms, A^2 l''/4: nanometres
        assert np.abs(window.position - theirs.position).max() < 0.002 * plan.amplitude


def test_corrected_windows_splice_continuously_and_the_whole_is_smooth(robot, plan):
    windows, schedule = streamed(robot, plan, {1.0: 1.2 * np.exp(0.3j), 2.0: 0.9})
    assert len(schedule.changes) == 3
    for before, after in zip(windows, windows[1:]):
        k = int(np.flatnonzero(np.isclose(before.times, after.times[0]))[0])
        for a, b in ((before.position, after.position), (before.velocity, after.velocity),
                     (before.acceleration, after.acceleration)):
            assert np.abs(a[k] - b[0]).max() < 1e-15
    # the signal the units follow: each window up to the next one's start
    times, pos, vel = [], [], []
    for window, following in zip(windows, windows[1:] + [None]):
        keep = window.times < following.times[0] if following is not None else np.ones(window.times.size, bool)
        times.append(window.times[keep])
        pos.append(window.position[keep])
        vel.append(window.velocity[keep])
    t, x, v = np.concatenate(times), np.concatenate(pos), np.concatenate(vel)
    dt = np.diff(t)
    assert np.allclose(dt, 0.001)
    # central differences at 1 kHz of a 35 Hz sine are (w dt)^2 / 6 = 0.8 % low: a step would be far more
    np.testing.assert_allclose(np.gradient(x, t, axis=0)[1:-1], v[1:-1], atol=0.012 * np.abs(v).max())
    # after the blends, the corrected amplitude: 1.2 x, then 0.9 x the plan's legs
    steady = (t > 1.6) & (t < 1.9)
    assert abs(np.abs(x[steady]).max(axis=0) / np.abs(plan.gains * plan.amplitude) - 1.2).max() < 0.01


def test_a_corrected_vibration_is_accepted_by_the_emulators_splice_checks(robot, plan):
    """Every window of a corrected vibration commanded to the in-process emulator, which refuses a window that
    does not continue the previous one (position, velocity) or starts in its ramp-out."""
    from emulator_runs import move_and_settle

    from stewart_vibration.emulation.emulator import HardwareEmulator
    from stewart_vibration.robot import VIB_NAMES
    from stewart_vibration.sim.mjcf import load_simulation_settings

    emu = HardwareEmulator(robot, load_simulation_settings(timestep=1 / 2000))
    move_and_settle(emu, robot, paper_pose(robot), settle_s=0.1)
    u0 = decomposition_demands(plan)
    schedule = DemandSchedule(u0, F, blend_s=0.1)
    stream = VibrationStream(robot, plan, StreamSettings(duration=None), demands=schedule)
    t0 = emu.time + 0.3
    for factor in [None, 1.1 * np.exp(0.2j), 0.8, None, 1.05]:
        now = emu.time - t0
        if factor is not None:
            schedule.correct(u0 * factor, stream.splice_time(now))
        window = stream.next_window(now)
        emu.command_vibration(VIB_NAMES, t0, window.times, window.position, window.velocity, window.acceleration)
        for _ in range(250):  # 0.5 s
            emu.advance(0.002)
    report, _ = emu.vibration_report()
    assert report.state == "running" and emu.fault is None, report
    # the check can fail: a correction blended in before the splice changes what was sent, and is refused
    now = emu.time - t0
    schedule.correct(u0 * 1.5, stream.splice_time(now) - 0.05)
    window = stream.next_window(now)
    with pytest.raises(VibrationLimitError, match="discontinuous splice"):
        emu.command_vibration(VIB_NAMES, t0, window.times, window.position, window.velocity, window.acceleration)


def test_a_correction_may_not_overlap_the_blend_before_it(plan):
    schedule = DemandSchedule(decomposition_demands(plan), F, blend_s=0.1)
    schedule.correct(decomposition_demands(plan) * 1.1, 1.0)
    with pytest.raises(InvalidInputError, match="overlaps"):
        schedule.correct(decomposition_demands(plan), 1.05)
    with pytest.raises(InvalidInputError):
        DemandSchedule(np.full(6, np.nan), F)
