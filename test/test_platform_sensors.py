"""The platform IMU and optical tracker (emulation.platform_sensors) against closed forms: the noise RMS of a
white density over the Nyquist band, the specific force of a body at rest and in free fall, the tracker's
rate, latency and noise."""

from __future__ import annotations

import numpy as np

from stewart_vibration.emulation.platform_sensors import (
    PlatformImu,
    PlatformTracker,
    band_rms,
    orientation_error_vector,
    quaternion_from_rotation_vector,
    quaternion_multiply,
    specific_force,
)
from stewart_vibration.kinematics.rotations import quaternion_from_rpy, rotation_from_rpy

GRAVITY = np.array([0.0, 0.0, -9.81])


def test_an_accelerometer_at_rest_reads_gravity_up_in_its_own_frame_and_zero_in_free_fall():
    rpy = np.array([0.1, -0.2, 0.3])
    rotation = rotation_from_rpy(rpy)
    at_rest = specific_force(rotation, np.zeros(3), GRAVITY)
    assert np.allclose(rotation @ at_rest, [0.0, 0.0, 9.81], atol=1e-12)  # +g up, seen from the world
    assert np.allclose(specific_force(rotation, GRAVITY, GRAVITY), 0.0, atol=1e-12)


def test_imu_noise_rms_and_bias_match_the_configured_density_and_bias():
    rate, density, gyro_density = 500.0, 6e-4, 5e-5
    bias, gyro_bias = np.array([0.01, -0.02, 0.005]), np.array([1e-4, 0.0, -3e-4])
    imu = PlatformImu(rate, density, gyro_density, bias, gyro_bias, rng=np.random.default_rng(1))
    truth = np.array([0.0, 0.0, 9.81])
    samples = [imu.read(truth, np.zeros(3)) for _ in range(20000)]
    accel = np.array([s.linear_acceleration for s in samples]) - truth
    gyro = np.array([s.angular_velocity for s in samples])
    expected = density * np.sqrt(rate / 2)
    assert np.isclose(band_rms(density, rate), expected)
    assert np.allclose(accel.std(axis=0) / expected, 1.0, atol=0.03)
    assert np.allclose(gyro.std(axis=0) / (gyro_density * np.sqrt(rate / 2)), 1.0, atol=0.03)
    assert np.allclose(accel.mean(axis=0), bias, atol=4 * expected / np.sqrt(len(samples)))
    assert np.allclose(gyro.mean(axis=0), gyro_bias, atol=4 * band_rms(gyro_density, rate) / np.sqrt(len(samples)))
    assert np.isclose(samples[0].accel_variance, expected ** 2)


def test_a_noiseless_imu_reads_the_truth_exactly():
    imu = PlatformImu(500.0)
    sample = imu.read([1.0, 2.0, 3.0], [0.1, 0.2, 0.3])
    assert np.array_equal(sample.linear_acceleration, [1.0, 2.0, 3.0])
    assert np.array_equal(sample.angular_velocity, [0.1, 0.2, 0.3])


def test_tracker_frames_come_at_its_rate_after_its_latency_with_their_capture_stamps():
    tracker = PlatformTracker(60.0, latency_s=0.01)
    dt, delivered = 0.002, []
    for k in range(1000):  # 2 s of 500 Hz state periods; the pose encodes the time
        t = k * dt
        for frame in tracker.step(t, [t, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]):
            delivered.append((t, frame))
    stamps = np.array([f.stamp for _, f in delivered])
    assert abs(len(stamps) - 2.0 * 60.0) <= 2
    assert np.allclose(np.diff(stamps).mean(), 1 / 60.0, rtol=0.01)
    assert np.all(np.diff(stamps) <= 1 / 60.0 + dt + 1e-9)
    latency = np.array([t - f.stamp for t, f in delivered])
    assert np.all((latency >= 0.01 - 1e-9) & (latency < 0.01 + dt))
    assert np.allclose([f.position[0] for _, f in delivered], stamps)  # the pose of its capture time


def test_tracker_noise_matches_its_position_and_orientation_rms():
    tracker = PlatformTracker(500.0, position_noise_m=2e-5, orientation_noise_deg=0.005,
                              rng=np.random.default_rng(4))
    true_q = quaternion_from_rpy(np.array([0.05, 0.02, -0.1]))
    position = np.array([0.01, -0.02, 0.2])
    frames = [f for k in range(5000) for f in tracker.step(k * 0.002, position, true_q)]
    errors = np.array([f.position - position for f in frames])
    angles = np.degrees(np.array([orientation_error_vector(f.quaternion, true_q) for f in frames]))
    assert len(frames) > 4900
    assert np.allclose(errors.std(axis=0) / 2e-5, 1.0, atol=0.05)
    assert np.allclose(angles.std(axis=0) / 0.005, 1.0, atol=0.05)
    assert np.allclose(errors.mean(axis=0), 0.0, atol=4 * 2e-5 / np.sqrt(len(frames)))
    assert np.allclose([np.linalg.norm(f.quaternion) for f in frames], 1.0, atol=1e-12)


def test_quaternion_helpers_agree_with_rotation_matrices():
    phi = np.array([0.3, -0.2, 0.1])
    q = quaternion_from_rotation_vector(phi)
    base = quaternion_from_rpy(np.array([0.2, 0.1, -0.4]))
    composed = quaternion_multiply(base, q)
    angle = np.linalg.norm(phi)  # the vee of R - R^T over 2 is sin(angle) along the axis
    assert np.allclose(orientation_error_vector(composed, base), np.sin(angle) * phi / angle, atol=1e-12)
    tiny = np.array([1e-7, -2e-7, 3e-7])
    assert np.allclose(orientation_error_vector(quaternion_multiply(base, quaternion_from_rotation_vector(tiny)),
                                                base), tiny, atol=1e-13)
