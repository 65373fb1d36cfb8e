"""The emulator node's command decisions without ROS (emulation.command_intake): the lifecycle and size
refusals before a message is read, with their outcome codes; taking a leg trajectory and a vibration window on
an in-process emulator; the numbered answer to each leg trajectory and its final strut lengths."""

from __future__ import annotations

import threading
from types import SimpleNamespace

import numpy as np
import pytest

from stewart_vibration import inverse_kinematics
from stewart_vibration.emulation.command_intake import (
    LegTrajectoryAnswers,
    final_leg_positions,
    lifecycle_refusal,
    refuse_unread,
    take_leg_trajectory,
    take_vibration_window,
)
from stewart_vibration.emulation.command_size import LEG_TRAJECTORY, VIBRATION_WINDOW, max_message_bytes
from stewart_vibration.emulation.emulator import HardwareEmulator
from stewart_vibration.errors import RefusedError, StrokeLimitError
from stewart_vibration.robot import LEG_NAMES, VIB_NAMES
from stewart_vibration.sim.mjcf import load_simulation_settings


def trajectory(names, stamp, times, positions):
    """A decoded JointTrajectory as messages.joint_trajectory.decode_joint_trajectory gives it."""
    return SimpleNamespace(names=tuple(names), stamp=stamp, times=np.asarray(times, float),
                           positions=None if positions is None else np.asarray(positions, float),
                           velocities=None, accelerations=None)


@pytest.fixture
def emulator(robot, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo may write MUJOCO_LOG.TXT in the working directory
    emu = HardwareEmulator(robot, load_simulation_settings(timestep=1 / 2000))
    emu.advance(0.002)
    return emu


def test_commands_are_refused_unless_configured_and_active():
    assert "unconfigured" in lifecycle_refusal(configured=False, active=False)
    assert "inactive" in lifecycle_refusal(configured=True, active=False)
    assert lifecycle_refusal(configured=True, active=True) is None


@pytest.mark.parametrize("kind", [LEG_TRAJECTORY, VIBRATION_WINDOW])
def test_an_unread_command_is_refused_for_the_lifecycle_first_then_for_its_size(kind):
    too_big = bytes(max_message_bytes(kind) + 1)
    with pytest.raises(RefusedError) as inactive:
        refuse_unread("the hardware emulator is inactive (lifecycle: activate it)", too_big, kind)
    assert inactive.value.outcome == "ROBOT_INACTIVE" and "inactive" in str(inactive.value)
    with pytest.raises(RefusedError) as oversized:
        refuse_unread(None, too_big, kind)
    assert oversized.value.outcome == "LIMIT_EXCEEDED" and f"{len(too_big)} bytes" in str(oversized.value)
    refuse_unread(None, bytes(max_message_bytes(kind)), kind)  # at the bound: read


def test_final_leg_positions_follow_the_names_not_the_column_order():
    names = ["leg_3", "vib_1", "leg_1", "leg_2", "leg_6", "leg_5", "leg_4"]
    positions = np.array([[0.0] * 7, [3.0, 9.0, 1.0, 2.0, 6.0, 5.0, 4.0]])
    assert final_leg_positions(names, positions) == pytest.approx([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    partial = final_leg_positions(["leg_2", "leg_1"], np.array([[0.2, 0.1]]))
    assert partial[:2] == pytest.approx([0.1, 0.2]) and np.isnan(partial[2:]).all()  # unnamed legs: NaN
    assert np.isnan(final_leg_positions(["leg_1", "leg_2"], np.array([[0.1]]))[1])  # named without a column
    assert np.isnan(final_leg_positions(LEG_NAMES, None)).all()  # points without positions
    assert np.isnan(final_leg_positions(LEG_NAMES, np.empty((0, 6)))).all()


def test_every_leg_trajectory_gets_the_next_number_taken_or_refused():
    answers = LegTrajectoryAnswers()
    refused = answers.answer(None, RefusedError("ROBOT_INACTIVE", "inactive"), float("nan"), 0.0)
    assert (refused.seq, refused.accepted, refused.points) == (1, False, 0)
    assert np.isnan(refused.final_positions).all() and np.isnan(refused.end_time_s)
    traj = trajectory(LEG_NAMES, 0.0, [0.5, 1.0], np.full((2, 6), 0.18))
    taken = answers.answer(traj, None, 3.5, 2.5)
    assert (taken.seq, taken.accepted, taken.points, taken.end_time_s, taken.stamp_s) == (2, True, 2, 3.5, 2.5)
    assert taken.final_positions == pytest.approx([0.18] * 6)


def test_a_leg_trajectory_taken_ends_when_its_last_point_is_due(robot, emulator):
    pose = robot.home_pose.copy()
    pose[2] += 0.002
    lengths = inverse_kinematics(robot, pose)
    now = emulator.time
    end = take_leg_trajectory(emulator, trajectory(LEG_NAMES, 0.0, [1.0], [lengths]), threading.Lock())
    assert end == pytest.approx(now + 1.0)  # stamp 0 = now
    assert emulator.struts.sample(end)[0].ravel() == pytest.approx(lengths)  # commanded lengths at the end


def test_a_leg_trajectory_beyond_the_stroke_raises_its_typed_error(robot, emulator):
    too_long = np.full((1, 6), robot.limits.stroke_max + 0.01)
    with pytest.raises(StrokeLimitError):
        take_leg_trajectory(emulator, trajectory(LEG_NAMES, 0.0, [5.0], too_long), threading.Lock())
    assert emulator.at_rest()


def test_a_vibration_window_answers_with_the_status_taken_or_refused(emulator):
    lock = threading.Lock()
    start = emulator.time + 0.1
    jump = trajectory(VIB_NAMES, start, [0.0, 0.01], np.full((2, 6), 1e-3))  # from rest to 1 mm at once
    report, error = take_vibration_window(emulator, jump, lock)
    assert error is not None and error.outcome == "LIMIT_EXCEEDED"
    assert (report.refused, report.accepted, report.event) == (1, 0, "refused")
    still = trajectory(VIB_NAMES, start, [0.0, 0.01, 0.02], np.zeros((3, 6)))
    report, error = take_vibration_window(emulator, still, lock)
    assert error is None
    assert (report.refused, report.accepted) == (1, 1)
    assert not lock.locked()
