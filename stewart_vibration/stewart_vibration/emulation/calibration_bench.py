"""Kinematic calibration against the emulated robot in process (no ROS): what benchmarks/calibration.py and
the calibration tests run. The emulator is set at rest at each pose (``place_at_rest``: the struts hold the
drawing's encoder lengths for it), settles, and its sensors are read over a window: the tracker's frames and
the strut readings (encoder plus unit sensor) and the legs' load cells; the truth (the plant's platform pose and
payload) only judges."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..calibration.identification import CalibrationData
from ..calibration.pose_average import average_window
from ..kinematics import forward_kinematics
from ..kinematics.rotations import rotation_from_rpy
from ..robot import Robot
from .emulator import HardwareEmulator

STATE_PERIOD_S = 0.002

@dataclass(frozen=True)
class BenchMeasurements:
    """The calibration data of K poses, the true platform poses (K, 6) (m, rad) and the load cells' mean readings
    (K, 6) (N) over the same windows."""

    data: CalibrationData
    truth: np.ndarray
    loads: np.ndarray

def measure_poses(emu: HardwareEmulator, poses: np.ndarray, settle_s: float = 0.3,
                  window_s: float = 1.0) -> BenchMeasurements:
    """Set the robot at rest at each pose (K, 6), wait ``settle_s`` and average its sensors over ``window_s``."""
    rate = emu.tracker.period
    steps = int(round(window_s / STATE_PERIOD_S))
    positions, rotations, readings, frames, truth, loads = [], [], [], [], [], []
    for pose in poses:
        emu.place_at_rest(pose)
        emu.advance(settle_s)
        emu.tracker_frames()  # frames captured before the window are not this pose's
        start = emu.time
        legs = np.empty((steps, 6))
        cells = np.empty((steps, 6))
        true_poses = np.empty((steps, 6))
        got = []
        for k in range(steps):
            emu.advance(STATE_PERIOD_S)
            _, pos, _, effort = emu.joint_state()
            legs[k] = pos[:6] + pos[6:12]
            cells[k] = effort[:6]
            true_poses[k] = emu.platform_pose()
            got.extend(emu.tracker_frames())
        stamps = np.array([f.stamp for f in got])
        measured = average_window(stamps, np.array([f.position for f in got]), np.array([f.quaternion for f in got]),
                                  legs, (start - 1e-9, emu.time), 1.0 / rate, loads=cells)
        positions.append(measured.position)
        rotations.append(measured.rotation)
        readings.append(measured.readings)
        frames.append(measured.frames)
        truth.append(true_poses.mean(axis=0))
        loads.append(measured.loads)
    data = CalibrationData(np.array(positions), np.array(rotations), np.array(readings), np.array(frames, float))
    return BenchMeasurements(data, np.array(truth), np.array(loads))

def pose_errors(model: Robot, readings: np.ndarray, truth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(position error (K,) m, orientation error (K,) rad) of FK of ``model`` at the strut readings (K, 6) m
    against the true poses (K, 6)."""
    fk = forward_kinematics(model, readings, guess=truth)
    position = np.linalg.norm(fk.pose[:, :3] - truth[:, :3], axis=1)
    relative = np.einsum("kba,kbc->kac", fk.rotation, rotation_from_rpy(truth[:, 3:]))
    angle = np.arccos(np.clip((np.trace(relative, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0))
    return position, angle

