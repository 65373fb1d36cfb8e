"""Steps the in-process emulator tests share (no ROS): a minimum-jerk move and the paper's vibration."""

from __future__ import annotations

import numpy as np

from stewart_vibration import inverse_kinematics
from stewart_vibration.motion.profiles import minimum_jerk, minimum_jerk_duration
from stewart_vibration.robot import LEG_NAMES, VIB_NAMES
from stewart_vibration.vibration import decompose_vibration
from stewart_vibration.vibration.streaming import StreamSettings, VibrationStream

PERIOD = 0.002  # state period (s): one block of physics steps


def move_and_settle(emu, robot, pose, settle_s: float = 0.5) -> np.ndarray:
    """Move from home to ``pose`` (minimum jerk, 10 mm/s, 0.5 s at least), then ``settle_s``; returns the true
    pose reached."""
    start, goal = inverse_kinematics(robot, robot.home_pose), inverse_kinematics(robot, pose)
    duration = minimum_jerk_duration(start, goal, 0.01, 0.5)
    times = np.linspace(duration / 40, duration, 40)
    emu.command_struts(LEG_NAMES, 0.0, times, *minimum_jerk(start, goal, duration, times))
    while emu.time < duration + settle_s:
        emu.advance(PERIOD)
    return emu.platform_pose()


def start_tibia_vibration(emu, robot, pose, duration_s: float = 2.0):
    """Command the uncompensated plan of a 35 Hz, 0.3 g vibration along the tibia axis (base z) at ``pose``,
    starting 0.3 s from now for ``duration_s``; returns (plan, start time t0)."""
    plan = decompose_vibration(robot, pose, [0.0, 0.0, 1.0], acceleration_g=0.3, frequency=35.0, method="exact")
    t0 = emu.time + 0.3
    window = VibrationStream(robot, plan, StreamSettings(duration=duration_s)).next_window(emu.time - t0)
    emu.command_vibration(VIB_NAMES, t0, window.times, window.position, window.velocity, window.acceleration)
    return plan, t0


def run_excitation(emu, steps, amplitude_m: float, lead_s: float = 0.1) -> dict:
    """Run the identification ``steps`` (vibration.identification_run) on the in-process emulator, each
    step's window commanded just before it starts; record every state period: times (s from t0), the unit
    sensors (N, 6), the IMU's specific force and rate (N, 3) each, and the truth for judging: the units' true
    displacements (N, 6) and the platform's true pose (N, 6)."""
    from stewart_vibration.vibration.identification_run import step_samples

    t0 = emu.time + lead_s
    rec: dict[str, list] = {"times": [], "units": [], "accel": [], "gyro": [], "true_units": [], "true_pose": []}
    for step in steps:
        while emu.time < t0 + step.start - 0.05:
            _record(emu, t0, rec)
        grid = np.arange(0.0, step.duration + 1e-9, 0.001)
        x, v, a = step_samples(step, amplitude_m, grid + step.start)
        emu.command_vibration(VIB_NAMES, t0 + step.start, grid, x, v, a)
    while emu.time < t0 + steps[-1].end + 0.02:
        _record(emu, t0, rec)
    return {key: np.asarray(value) for key, value in rec.items()}


def _record(emu, t0: float, rec: dict) -> None:
    emu.advance(PERIOD)
    _, positions, _, _ = emu.joint_state()
    imu = emu.imu_sample()
    rec["times"].append(emu.time - t0)
    rec["units"].append(positions[6:])
    rec["accel"].append(imu.linear_acceleration)
    rec["gyro"].append(imu.angular_velocity)
    rec["true_units"].append(emu.true_joint_state()[1][6:])
    rec["true_pose"].append(emu.platform_pose())
