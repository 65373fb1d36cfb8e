"""Rotation helpers: conventions checked against independent forms."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from reference import reference_rotation, rodrigues

from stewart_vibration.kinematics.rotations import (
    euler_rate_matrix,
    pose_from_position_quaternion,
    pose_to_position_quaternion,
    quaternion_from_rpy,
    rotation_from_quaternion,
    rotation_from_rpy,
    rpy_from_quaternion,
    rpy_from_rotation,
    so3_exp,
    so3_log,
    wrap_angle,
)

angle = st.floats(-3.0, 3.0)
pitch = st.floats(-1.5, 1.5)


@settings(max_examples=200, deadline=None)
@given(angle, pitch, angle)
def test_rotation_matches_paper_order(roll, p, yaw):
    assert np.allclose(rotation_from_rpy([roll, p, yaw]), reference_rotation(roll, p, yaw), atol=1e-14)


@settings(max_examples=200, deadline=None)
@given(angle, pitch, angle)
def test_rpy_round_trip(roll, p, yaw):
    rot = rotation_from_rpy([roll, p, yaw])
    assert np.allclose(rotation_from_rpy(rpy_from_rotation(rot)), rot, atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(angle, pitch, angle)
def test_quaternion_matches_rotation(roll, p, yaw):
    x, y, z, w = quaternion_from_rpy([roll, p, yaw])
    # textbook quaternion -> matrix
    rot = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    assert np.allclose(rot, rotation_from_rpy([roll, p, yaw]), atol=1e-12)
    assert np.allclose(rotation_from_quaternion([x, y, z, w]), reference_rotation(roll, p, yaw), atol=1e-12)
    rpy = rpy_from_quaternion([x, y, z, w])
    assert np.allclose(rotation_from_rpy(rpy), rot, atol=1e-9)


def test_quaternions_in_a_batch_give_the_rotations_of_each_alone():
    """The batched path ([..., 4]) and the one-quaternion path agree with the independent Euler reference."""
    rng = np.random.default_rng(5)
    rpy = rng.uniform([-np.pi, -1.4, -np.pi], [np.pi, 1.4, np.pi], (7, 3))
    quats = np.array([quaternion_from_rpy(a) for a in rpy])
    batch = rotation_from_quaternion(quats.reshape(7, 1, 4))
    assert batch.shape == (7, 1, 3, 3)
    for k, (roll, p, yaw) in enumerate(rpy):
        reference = reference_rotation(roll, p, yaw)
        assert np.abs(batch[k, 0] - reference).max() < 1e-12
        assert np.abs(rotation_from_quaternion(quats[k]) - reference).max() < 1e-12


def test_pose_quaternion_round_trip():
    rng = np.random.default_rng(0)
    poses = np.concatenate([rng.normal(size=(50, 3)), rng.uniform(-1, 1, (50, 3))], axis=1)
    position, quat = pose_to_position_quaternion(poses)
    assert np.allclose(np.linalg.norm(quat, axis=1), 1.0)
    assert np.allclose(pose_from_position_quaternion(position, quat), poses, atol=1e-12)


def test_euler_rate_matrix_by_finite_differences():
    rng = np.random.default_rng(1)
    for _ in range(20):
        theta = rng.uniform(-1, 1, 3)
        rate = rng.normal(size=3)
        h = 1e-6
        dr = (rotation_from_rpy(theta + h * rate) - rotation_from_rpy(theta - h * rate)) / (2 * h)
        omega_skew = dr @ rotation_from_rpy(theta).T  # [w]x in the base frame
        omega = np.array([omega_skew[2, 1], omega_skew[0, 2], omega_skew[1, 0]])
        assert np.allclose(euler_rate_matrix(theta) @ rate, omega, atol=1e-8)


def test_so3_exp_and_log():
    rng = np.random.default_rng(2)
    phis = np.concatenate([rng.normal(size=(20, 3)) * 0.8, rng.normal(size=(5, 3)) * 1e-9])
    for phi in phis:
        assert np.allclose(so3_exp(phi), rodrigues(phi), atol=1e-13)
    assert np.allclose(so3_log(so3_exp(phis)), phis, atol=1e-10)


def test_wrap_is_the_angle_of_the_unit_phasor_in_minus_pi_to_pi():
    angles = np.random.default_rng(5).uniform(-20, 20, 1000)
    wrapped = wrap_angle(angles)
    assert np.allclose(wrapped, np.angle(np.exp(1j * angles)), rtol=0, atol=1e-12)  # same direction
    assert (wrapped > -np.pi).all() and (wrapped <= np.pi).all()
    assert np.allclose(wrap_angle(np.array([np.pi, -np.pi, 3 * np.pi, 0.0, -0.5])), [np.pi, np.pi, np.pi, 0.0, -0.5],
                       rtol=0, atol=1e-12)  # the half-open end: -pi is pi
