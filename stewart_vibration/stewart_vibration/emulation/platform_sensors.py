"""The platform's own sensors: an IMU that sees the delivered vibration, and an external optical tracker.

Both take the truth from the physics and add what the device adds (plant file, ``sensors.imu`` and
``sensors.tracker``; emulation.plant.Sensors):

- ``PlatformImu``: a 3-axis accelerometer (specific force, m/s^2) and gyroscope (rad/s) at the platform
  origin, axes of the platform frame, sampled once per state period. Each sample is truth + a constant
  seeded bias + white noise of the configured density over the device's output band, taken as the
  Nyquist band of its sample rate: RMS = density * sqrt(rate / 2). The default figures (60 ug/sqrt(Hz),
  0.003 deg/s/sqrt(Hz), biases up to 2 mg and 0.03 deg/s) are those of an industrial MEMS IMU.
- ``PlatformTracker``: a pose of the platform frame in the base frame at ``rate_hz``, stamped with the
  capture time and delivered ``latency_s`` later, with white noise per axis on the position (m) and on
  the orientation (a small rotation, rad, applied in the platform frame).

Pure numpy; no ROS. The emulator calls ``read`` / ``capture`` once per state period.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from ..kinematics.rotations import rotation_from_quaternion


@dataclass(frozen=True)
class ImuSample:
    """One IMU sample: specific force (3,) m/s^2 and angular rate (3,) rad/s in the platform frame, and the
    per-axis noise variances the device states ((m/s^2)^2, (rad/s)^2; the message's covariance)."""

    linear_acceleration: np.ndarray
    angular_velocity: np.ndarray
    accel_variance: float
    gyro_variance: float


def band_rms(density: float, rate_hz: float) -> float:
    """RMS of white noise of ``density`` (unit/sqrt(Hz)) sampled at ``rate_hz`` over its Nyquist band."""
    return float(density) * float(np.sqrt(rate_hz / 2.0))


def specific_force(rotation: np.ndarray, acceleration_world: np.ndarray, gravity_world: np.ndarray) -> np.ndarray:
    """What an accelerometer at a point reads (3,) m/s^2, its frame: R^T (a - g), with the point's
    acceleration a and gravity g in the world frame and R the sensor frame's rotation in the world."""
    return np.asarray(rotation).T @ (np.asarray(acceleration_world, float) - np.asarray(gravity_world, float))


class PlatformImu:
    """The platform IMU: truth + bias + white noise (see the module docstring)."""

    def __init__(self, rate_hz: float, accel_density: float = 0.0, gyro_density: float = 0.0,
                 accel_bias=None, gyro_bias=None, rng: np.random.Generator | None = None):
        self.rate_hz = float(rate_hz)
        self.accel_rms = band_rms(accel_density, rate_hz)
        self.gyro_rms = band_rms(gyro_density, rate_hz)
        self.accel_bias = np.zeros(3) if accel_bias is None else np.asarray(accel_bias, float).reshape(3)
        self.gyro_bias = np.zeros(3) if gyro_bias is None else np.asarray(gyro_bias, float).reshape(3)
        self.rng = rng if rng is not None else np.random.default_rng(0)

    def read(self, specific_force_local, angular_velocity_local) -> ImuSample:
        """One sample from the true specific force and angular rate (3,) each, platform frame."""
        accel = np.asarray(specific_force_local, float) + self.accel_bias
        gyro = np.asarray(angular_velocity_local, float) + self.gyro_bias
        if self.accel_rms > 0:
            accel = accel + self.rng.normal(0.0, self.accel_rms, 3)
        if self.gyro_rms > 0:
            gyro = gyro + self.rng.normal(0.0, self.gyro_rms, 3)
        return ImuSample(accel, gyro, self.accel_rms ** 2, self.gyro_rms ** 2)


def quaternion_multiply(a, b) -> np.ndarray:
    """Hamilton product a * b of quaternions [x, y, z, w] (4,)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz])


def quaternion_from_rotation_vector(phi) -> np.ndarray:
    """Unit quaternion [x, y, z, w] (4,) of the rotation by vector ``phi`` (3,) rad."""
    phi = np.asarray(phi, float)
    angle = float(np.linalg.norm(phi))
    if angle < 1e-12:
        return np.r_[0.5 * phi, 1.0] / np.linalg.norm(np.r_[0.5 * phi, 1.0])
    return np.r_[np.sin(angle / 2) * phi / angle, np.cos(angle / 2)]


@dataclass(frozen=True)
class TrackerFrame:
    """One tracker measurement: capture time (s), position (3,) m and quaternion (4,) [x, y, z, w] of the
    platform frame in the base frame."""

    stamp: float
    position: np.ndarray
    quaternion: np.ndarray


class PlatformTracker:
    """An external optical tracker: frames captured at ``rate_hz`` (at the first state period at or after
    each capture instant), delivered ``latency_s`` after their capture (see the module docstring)."""

    def __init__(self, rate_hz: float, position_noise_m: float = 0.0, orientation_noise_deg: float = 0.0,
                 latency_s: float = 0.0, rng: np.random.Generator | None = None):
        self.period = 1.0 / float(rate_hz)
        self.position_noise_m = float(position_noise_m)
        self.orientation_noise_rad = float(np.radians(orientation_noise_deg))
        self.latency_s = float(latency_s)
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self._next_capture: float | None = None
        self._pending: deque[TrackerFrame] = deque()

    def restart(self) -> None:
        """Forget the frames in flight (the robot was rebuilt or reset)."""
        self._next_capture, self._pending = None, deque()

    def step(self, time: float, position, quaternion) -> list[TrackerFrame]:
        """Offer the true pose at ``time`` (s); returns the frames whose latency has passed by then."""
        if self._next_capture is None:
            self._next_capture = time
        if time >= self._next_capture - 1e-9:
            self._pending.append(self._measure(time, position, quaternion))
            self._next_capture += self.period * max(1.0, np.floor((time - self._next_capture) / self.period) + 1)
        due = []
        while self._pending and self._pending[0].stamp + self.latency_s <= time + 1e-9:
            due.append(self._pending.popleft())
        return due

    def _measure(self, time: float, position, quaternion) -> TrackerFrame:
        position = np.asarray(position, float).copy()
        quaternion = np.asarray(quaternion, float).copy()
        if self.position_noise_m > 0:
            position = position + self.rng.normal(0.0, self.position_noise_m, 3)
        if self.orientation_noise_rad > 0:
            noise = quaternion_from_rotation_vector(self.rng.normal(0.0, self.orientation_noise_rad, 3))
            quaternion = quaternion_multiply(quaternion, noise)
        return TrackerFrame(float(time), position, quaternion)


def orientation_error_vector(measured, true) -> np.ndarray:
    """The small rotation (3,) rad, platform frame, from quaternion ``true`` to ``measured`` [x, y, z, w]."""
    r = rotation_from_quaternion(np.asarray(true, float)).T @ rotation_from_quaternion(np.asarray(measured, float))
    return 0.5 * np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
