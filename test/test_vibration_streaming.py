"""Streaming a planned vibration as self-contained windows, checked against an independent
reference (IK of the displaced pose along the force line, the ramped sine written here) and against the
emulator's command buffer, which must accept every window and play a seamless vibration."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration import decompose_vibration, inverse_kinematics
from stewart_vibration.emulation.strut_trajectory import build_trajectory
from stewart_vibration.emulation.vibration_buffer import VibrationBuffer
from stewart_vibration.kinematics.rotations import rotation_from_rpy
from stewart_vibration.paper import paper_pose
from stewart_vibration.vibration.feasibility import check_command_limits
from stewart_vibration.vibration.streaming import StreamInterrupted, StreamSettings, VibrationStream

VIB = [f"vib_{i}" for i in range(1, 7)]
F, G = 35.0, 0.3
AMP = G * 9.80665 / (2 * np.pi * F) ** 2
RAMP = 0.2
T0 = 50.0  # absolute start (s)


@pytest.fixture
def plan(robot):
    return decompose_vibration(robot, paper_pose(robot), [0.0, 0.0, 1.0], acceleration_g=G, frequency=F,
                               method="exact")


def reference_legs(robot, t, duration=None, fade_at=None):
    """IK(pose + u delta(t)) - IK(pose) with delta = A e(t) sin(w t), e: quintic ramps (written here)."""
    def s(x):
        x = np.clip(x, 0.0, 1.0)
        return 10 * x**3 - 15 * x**4 + 6 * x**5

    t = np.asarray(t, float)
    e = s(t / RAMP) * (t >= 0)
    if duration is not None:
        e = e * s((duration - t) / RAMP) * (t <= duration)
    if fade_at is not None:
        e = e * s((fade_at + RAMP - t) / RAMP)
    pose = paper_pose(robot)
    u = rotation_from_rpy(pose[3:])[:, 2]  # platform z in the base frame (the tibia axis)
    displaced = np.tile(pose, (t.size, 1))
    displaced[:, :3] += (AMP * e * np.sin(2 * np.pi * F * t))[:, None] * u
    return inverse_kinematics(robot, displaced) - inverse_kinematics(robot, pose)


def to_buffer(buffer, window, now):
    traj = build_trajectory(VIB, VIB, T0, window.times, window.position, window.velocity, window.acceleration)
    return buffer.add(traj, now)


def test_finite_vibration_fits_in_one_window_from_rest_to_rest(robot, plan):
    stream = VibrationStream(robot, plan, StreamSettings(duration=3.0, ramp_s=RAMP))
    window = stream.next_window(-1.0)
    assert window.final and stream.finished and stream.next_window(0.5) is None
    assert window.times[0] == 0.0 and window.times[-1] == pytest.approx(3.0) and len(window.times) == 3001
    assert np.abs(window.position[[0, -1]]).max() == 0.0 and np.abs(window.velocity[[0, -1]]).max() < 1e-15
    np.testing.assert_allclose(window.position, reference_legs(robot, window.times, duration=3.0), atol=1e-12)
    check_command_limits(robot.vibration_unit, window.times, window.position, window.velocity, window.acceleration)


def test_streamed_windows_agree_end_at_rest_and_splice_seamlessly(robot, plan):
    s = StreamSettings(duration=None, ramp_s=RAMP, lookahead_s=1.5, lead_s=0.3)
    stream = VibrationStream(robot, plan, s)
    buffer = VibrationBuffer(robot.vibration_unit)
    sent, now = [], -1.0
    while now < 4.0:
        window = stream.next_window(now)
        assert not window.final
        assert np.abs(window.position[-1]).max() < 1e-18 and np.abs(window.velocity[-1]).max() < 1e-15  # safe alone
        assert stream.tail_start >= window.times[0] + s.lookahead_s - 1e-9
        for earlier in sent:  # overlapping samples before the earlier tail are the same numbers
            common, i, j = np.intersect1d(np.round(earlier.times, 6), np.round(window.times, 6), return_indices=True)
            before_tail = common < earlier.rest_at - RAMP - 1e-9
            np.testing.assert_array_equal(earlier.position[i[before_tail]], window.position[j[before_tail]])
        to_buffer(buffer, window, T0 + now)  # accepted as a continuous splice
        sent.append(window)
        t = np.arange(now, now + 0.5, 0.0005)  # what the units play until the next window
        assert np.abs(buffer.sample(T0 + t)[0] - reference_legs(robot, t)).max() < 1e-9  # no tail dip
        now += 0.5
    assert len(sent) == 10


def test_a_stall_past_the_lookahead_ramps_out_and_is_reported(robot, plan):
    s = StreamSettings(duration=None, ramp_s=RAMP, lookahead_s=1.0, lead_s=0.3)
    stream = VibrationStream(robot, plan, s)
    buffer = VibrationBuffer(robot.vibration_unit)
    to_buffer(buffer, stream.next_window(-1.0), T0 - 1.0)
    to_buffer(buffer, stream.next_window(0.5), T0 + 0.5)
    tail = stream.tail_start
    with pytest.raises(StreamInterrupted) as err:
        stream.next_window(tail)  # held up: the next window would start after the tail began
    assert err.value.at == pytest.approx(tail) and "ran out of commands" in str(err.value)
    t = np.arange(tail - 0.5, tail + RAMP + 0.5, 0.0005)
    pos, vel, _ = buffer.sample(T0 + t)
    np.testing.assert_allclose(pos, reference_legs(robot, t, fade_at=tail), atol=1e-9)  # the planned tail
    assert np.abs(pos[t >= tail + RAMP]).max() == 0.0
    assert buffer.status(T0 + tail + RAMP + 0.2).state == "idle"


def test_a_stall_judged_by_its_length_agrees_with_the_units_buffer(robot, plan):
    """check_stall (the planner's judgement on waking, before a fresh clock): interrupted exactly when the
    units' own buffer is no longer at full amplitude where the next window would start."""
    s = StreamSettings(duration=None, ramp_s=RAMP, lookahead_s=1.0, lead_s=0.3)
    stream = VibrationStream(robot, plan, s)
    buffer = VibrationBuffer(robot.vibration_unit)
    to_buffer(buffer, stream.next_window(-1.0), T0 - 1.0)
    seen = 0.5
    to_buffer(buffer, stream.next_window(seen), T0 + seen)
    for held_up in (0.0, 0.3, 0.95, 1.05, 2.0, 5.0):
        starts_at = seen + held_up + s.lead_s  # where a window sent on waking would start
        t = np.arange(starts_at - 0.05, starts_at, 0.0005)
        full = np.allclose(buffer.sample(T0 + t)[0], reference_legs(robot, t), atol=1e-9)
        try:
            stream.check_stall(seen, held_up)
            interrupted = False
        except StreamInterrupted as exc:
            interrupted = True
            assert f"held up {held_up:.3f} s of sim time" in str(exc) and "ran out of commands" in str(exc)
            assert exc.at == pytest.approx(stream.tail_start)
        assert interrupted == (not full), held_up
    assert stream.tail_start == pytest.approx(1.8)  # the cases above straddle it (1.05 and 0.95)
    stream.stop_window(seen)
    stream.check_stall(seen, 5.0)  # stopping: the stop window ends the vibration, nothing is left to judge


def test_stop_ramps_out_from_a_sent_sample(robot, plan):
    s = StreamSettings(duration=None, ramp_s=RAMP)
    stream = VibrationStream(robot, plan, s)
    buffer = VibrationBuffer(robot.vibration_unit)
    to_buffer(buffer, stream.next_window(-1.0), T0 - 1.0)
    to_buffer(buffer, stream.next_window(0.5), T0 + 0.5)
    stop = stream.stop_window(0.9)
    assert stop.final and stream.finished and stream.next_window(1.0) is None
    assert stream.stop_at == pytest.approx(1.2) and stream.planned_end == pytest.approx(1.2 + RAMP)
    to_buffer(buffer, stop, T0 + 0.9)
    t = np.arange(0.9, 2.0, 0.0005)  # from now on (the buffer keeps a second of history)
    np.testing.assert_allclose(buffer.sample(T0 + t)[0], reference_legs(robot, t, fade_at=1.2), atol=1e-9)


@pytest.mark.parametrize("duration", [None, 60.0])
def test_a_stop_before_t0_replaces_what_the_units_hold_with_rest(robot, plan, duration):
    """A vibration stopped before it begins (its first window, ramp-in and all, already in the units' buffer)
    never moves a unit: the stop window holds rest from t0, and the buffer plays nothing past it."""
    stream = VibrationStream(robot, plan, StreamSettings(duration=duration, ramp_s=RAMP))
    buffer = VibrationBuffer(robot.vibration_unit)
    to_buffer(buffer, stream.next_window(-1.0), T0 - 1.0)
    stop = stream.stop_window(-0.9)
    assert stop.final and stream.finished and stream.next_window(0.0) is None
    assert stop.times[0] == 0.0 and stop.rest_at == pytest.approx(RAMP) and stream.planned_end == pytest.approx(RAMP)
    to_buffer(buffer, stop, T0 - 0.9)
    t = np.arange(-0.5, 3.0, 0.0005)
    assert np.abs(buffer.sample(T0 + t)[0]).max() == 0.0


def test_stop_during_a_whole_finite_vibration_and_after_its_ramp_out_began(robot, plan):
    stream = VibrationStream(robot, plan, StreamSettings(duration=3.0, ramp_s=RAMP))
    stream.next_window(-1.0)
    assert stream.stop_window(1.0) is not None and stream.planned_end == pytest.approx(1.3 + RAMP)
    late = VibrationStream(robot, plan, StreamSettings(duration=3.0, ramp_s=RAMP))
    late.next_window(-1.0)
    assert late.stop_window(2.6) is None and late.planned_end == pytest.approx(3.0)  # already ramping out


def test_a_correction_after_the_final_window_replaces_its_rest_until_the_ramp_out(robot, plan):
    """A finite vibration sent whole, then its demands changed (a closed loop's correction): the correction
    window runs from the splice to the end, the units' buffer takes it as a continuous splice, and the units
    then play the corrected demands (blended in over blend_s); once the splice would fall in the ramp-out,
    or after a stop, nothing more can be sent."""
    from stewart_vibration.vibration.demand_schedule import DemandSchedule
    from stewart_vibration.vibration.leg_demands import decomposition_demands

    initial = decomposition_demands(plan)
    schedule = DemandSchedule(initial, F, blend_s=0.05)
    settings = StreamSettings(duration=3.0, ramp_s=RAMP, lead_s=0.3)
    stream = VibrationStream(robot, plan, settings, demands=schedule)
    buffer = VibrationBuffer(robot.vibration_unit)
    assert not stream.can_correct(-1.0)  # nothing sent yet: the first window is the plan itself
    first = stream.next_window(-1.0)
    assert first.final and stream.finished and stream.can_correct(1.0)
    to_buffer(buffer, first, T0 - 1.0)
    corrected = initial * 1.1 * np.exp(0.2j)
    schedule.correct(corrected, stream.splice_time(1.0))
    window = stream.correction_window(1.0)
    assert window.final and window.times[0] == pytest.approx(1.3) and window.times[-1] == pytest.approx(3.0)
    to_buffer(buffer, window, T0 + 1.0)  # the units' own splice check: continuous in position and velocity
    t = np.arange(1.4, 2.7, 0.0005)
    carrier = np.imag(corrected[None, :] * np.exp(2j * np.pi * F * t)[:, None])
    np.testing.assert_allclose(buffer.sample(T0 + t)[0], carrier, atol=1e-9 * AMP)
    # the splice of a change at 2.6 s would be at 2.9 s, in the ramp-out (from 2.8 s): too late to correct
    assert stream.can_correct(2.49) and not stream.can_correct(2.51) and stream.correction_window(2.6) is None
    stopped = VibrationStream(robot, plan, settings, demands=DemandSchedule(initial, F))
    stopped.next_window(-1.0)
    stopped.stop_window(1.0)
    assert not stopped.can_correct(1.1) and stopped.correction_window(1.1) is None
    uncorrectable = VibrationStream(robot, plan, settings)  # the plan's exact signals: no demands to change
    uncorrectable.next_window(-1.0)
    assert not uncorrectable.can_correct(1.0)


def test_an_infeasible_plan_fails_the_shared_limit_check(robot):
    strong = decompose_vibration(robot, paper_pose(robot), [0.0, 0.0, 1.0], acceleration_g=1.2, frequency=60.0,
                                 method="exact", check_limits=False)  # not checked here: the window check must catch it
    window = VibrationStream(robot, strong, StreamSettings(duration=1.0, ramp_s=0.2)).next_window(-1.0)
    from stewart_vibration import VibrationLimitError

    with pytest.raises(VibrationLimitError) as err:  # 1.2 g along the axis: legs beyond their 1 g
        check_command_limits(robot.vibration_unit, window.times, window.position, window.velocity, window.acceleration)
    assert err.value.limit_name == "acceleration_max"
