"""Steps the in-process emulator tests share (no ROS): a minimum-jerk move and the paper's vibration."""

from __future__ import annotations

import numpy as np

from stewart_vibration.emulation.control_bench import move_to
from stewart_vibration.robot import VIB_NAMES
from stewart_vibration.vibration import decompose_vibration
from stewart_vibration.vibration.streaming import StreamSettings, VibrationStream

PERIOD = 0.002  # state period (s): one block of physics steps


def move_and_settle(emu, robot, pose, settle_s: float = 0.5) -> np.ndarray:
    """Move from home to ``pose`` (minimum jerk, 10 mm/s, 0.5 s at least), then ``settle_s``; returns the true
    pose reached."""
    move_to(emu, robot, pose, settle_s)
    return emu.platform_pose()


def start_tibia_vibration(emu, robot, pose, duration_s: float = 2.0):
    """Command the uncompensated plan of a 35 Hz, 0.3 g vibration along the tibia axis (base z) at ``pose``,
    starting 0.3 s from now for ``duration_s``; returns (plan, start time t0)."""
    plan = decompose_vibration(robot, pose, [0.0, 0.0, 1.0], acceleration_g=0.3, frequency=35.0, method="exact")
    t0 = emu.time + 0.3
    window = VibrationStream(robot, plan, StreamSettings(duration=duration_s)).next_window(emu.time - t0)
    emu.command_vibration(VIB_NAMES, t0, window.times, window.position, window.velocity, window.acceleration)
    return plan, t0

