"""Decomposition: gains, phases, exact vs linear, FFT, rotation, amplitude units."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from vibration_reference import jacobian_ref, legs, rodrigues, rpy_matrix

from stewart_vibration import decompose_vibration, inverse_kinematics
from stewart_vibration.errors import InvalidInputError
from stewart_vibration.paper import (
    CLINICAL_ACCELERATION_G,
    CLINICAL_FREQUENCY_HZ,
    PAPER_AMPLITUDE_M,
    PAPER_FREQUENCY_HZ,
    PAPER_PHASE_RAD,
    paper_pose,
)

G = 9.80665


@pytest.fixture(scope="module")
def pose(robot):
    return paper_pose(robot)


def reference_gains(robot, pose, u_base):
    _, _, n = jacobian_ref(robot, pose)
    return n @ u_base


def test_default_direction_is_platform_z_and_gains_equal_n_dot_u(robot, pose):
    plan = decompose_vibration(robot, pose, amplitude=PAPER_AMPLITUDE_M, frequency=PAPER_FREQUENCY_HZ,
                               phase=PAPER_PHASE_RAD)
    u = rpy_matrix(*pose[3:])[:, 2]
    np.testing.assert_allclose(plan.direction, u, atol=1e-15)
    np.testing.assert_allclose(plan.gains, reference_gains(robot, pose, u), atol=1e-12, rtol=0)
    np.testing.assert_allclose(plan.leg_amplitudes, np.abs(plan.gains) * PAPER_AMPLITUDE_M, rtol=1e-15)
    assert plan.frequency == PAPER_FREQUENCY_HZ
    assert np.all(plan.gains > 0)  # tibia axis: every leg lengthens together here
    np.testing.assert_allclose(plan.leg_phases, PAPER_PHASE_RAD)


def test_lateral_direction_gives_mixed_signs_and_antiphase(robot, pose):
    phase = 0.4
    plan = decompose_vibration(robot, pose, direction=[1.0, 0.0, 0.0], amplitude=20e-6, frequency=30.0,
                               phase=phase, frame="platform")
    u = rpy_matrix(*pose[3:])[:, 0]
    ref = reference_gains(robot, pose, u)
    np.testing.assert_allclose(plan.gains, ref, atol=1e-12, rtol=0)
    assert (ref > 0).any() and (ref < 0).any(), "a lateral direction must give mixed signs"
    expected = np.where(ref < 0, phase + np.pi, phase) % (2 * np.pi)
    np.testing.assert_allclose(plan.leg_phases, expected, atol=1e-15)
    # the leg equations reproduce the signed linear signals
    t = plan.times[:, None]
    eq = plan.leg_amplitudes * np.sin(2 * np.pi * plan.frequency * t + plan.leg_phases)
    np.testing.assert_allclose(eq, plan.linear_signals, atol=1e-18)


@pytest.mark.parametrize("phase", [-1.0, 7.0, 4 * np.pi + 0.5])
def test_leg_phases_are_wrapped_to_one_turn(robot, pose, phase):
    plan = decompose_vibration(robot, pose, direction=[1.0, 0.0, 0.0], amplitude=20e-6, frequency=30.0,
                               phase=phase, frame="platform")
    k = reference_gains(robot, pose, rpy_matrix(*pose[3:])[:, 0])
    expected = np.where(k < 0, phase + np.pi, phase)
    assert np.all((plan.leg_phases >= 0) & (plan.leg_phases < 2 * np.pi))
    np.testing.assert_allclose(np.exp(1j * plan.leg_phases), np.exp(1j * expected), rtol=0, atol=1e-12)


@settings(max_examples=25, deadline=None)
@given(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1), st.sampled_from(["base", "platform"]))
def test_random_direction_gains(robot, x, y, z, frame):
    v = np.array([x, y, z])
    assume(np.linalg.norm(v) >= 1e-3)  # a direction must be given (zero is rejected, tested below)
    pose = paper_pose(robot)
    plan = decompose_vibration(robot, pose, direction=v, amplitude=1e-6, frequency=10.0, frame=frame,
                               method="linear")
    u = v / np.linalg.norm(v)
    if frame == "platform":
        u = rpy_matrix(*pose[3:]) @ u
    ref = reference_gains(robot, pose, u)
    np.testing.assert_allclose(plan.gains, ref, atol=1e-12, rtol=0)
    assert np.all(np.sign(plan.gains[np.abs(ref) > 1e-9]) == np.sign(ref[np.abs(ref) > 1e-9]))


def test_acceleration_amplitude_conversion(robot, pose):
    plan = decompose_vibration(robot, pose, acceleration_g=CLINICAL_ACCELERATION_G, frequency=CLINICAL_FREQUENCY_HZ)
    expected = 0.3 * G / (2 * np.pi * 35.0) ** 2
    assert plan.amplitude == pytest.approx(expected, rel=1e-14)
    assert 60e-6 < plan.amplitude < 62e-6  # ~61 um
    default = decompose_vibration(robot, pose)  # clinical default: 35 Hz, 0.3 g
    assert default.amplitude == pytest.approx(expected, rel=1e-14)
    # per-leg peak acceleration ~ |k| * 0.3 g (second order: relative ~ A / l)
    np.testing.assert_allclose(plan.peak_leg_acceleration, np.abs(plan.gains) * 0.3 * G, rtol=2e-3)


@pytest.mark.parametrize("amplitude,frequency", [(PAPER_AMPLITUDE_M, PAPER_FREQUENCY_HZ), (None, 35.0)])
def test_exact_minus_linear_matches_second_order(robot, pose, amplitude, frequency):
    plan = decompose_vibration(robot, pose, amplitude=amplitude, frequency=frequency, phase=PAPER_PHASE_RAD)
    _, lengths, n = jacobian_ref(robot, pose)
    k = n @ plan.direction
    delta = plan.delta[:, None]
    predicted = (1 - k**2) * delta**2 / (2 * lengths)
    diff = plan.exact_signals - plan.linear_signals
    np.testing.assert_allclose(plan.curvature, (1 - k**2) / lengths, rtol=1e-12)
    np.testing.assert_allclose(plan.second_order_offset, (1 - k**2) * plan.amplitude**2 / (4 * lengths), rtol=1e-12)
    peak = np.abs(predicted).max(axis=0)
    assert np.all(np.abs(diff - predicted).max(axis=0) <= 0.05 * peak)
    # the exact signals are the IK difference of the displaced poses (independent IK path)
    shifted = np.tile(pose, (delta.shape[0], 1))
    shifted[:, :3] += delta * plan.direction
    ik = inverse_kinematics(robot, shifted) - inverse_kinematics(robot, pose)
    np.testing.assert_allclose(plan.exact_signals, ik, atol=5e-16, rtol=0)


@pytest.mark.parametrize("amplitude,frequency", [(PAPER_AMPLITUDE_M, PAPER_FREQUENCY_HZ), (None, 35.0)])
def test_fft_of_exact_signals(robot, pose, amplitude, frequency):
    plan = decompose_vibration(robot, pose, direction=[0.3, -0.5, 1.0], amplitude=amplitude, frequency=frequency,
                               phase=PAPER_PHASE_RAD, samples_per_period=512)
    _, lengths, n = jacobian_ref(robot, pose)
    k = n @ plan.direction
    a = plan.amplitude
    spectrum = np.fft.rfft(plan.exact_signals, axis=0) / plan.times.size
    fundamental = 2 * np.abs(spectrum[1])
    second = 2 * np.abs(spectrum[2])
    dc = spectrum[0].real
    big = np.abs(k) > 0.05
    assert big.sum() >= 4
    np.testing.assert_allclose(fundamental[big], np.abs(k[big]) * a, rtol=1e-6)
    ratio_pred = (1 - k**2) * a / (4 * lengths * np.abs(k))
    np.testing.assert_allclose((second / fundamental)[big], ratio_pred[big], rtol=1e-2)
    np.testing.assert_allclose(dc, (1 - k**2) * a**2 / (4 * lengths), rtol=1e-2)
    # phase of the fundamental: phase for k > 0, phase + pi for k < 0 (sin -> -i/2 e^{i phi})
    phase = np.angle(spectrum[1] * 2j)
    expected = np.where(k < 0, PAPER_PHASE_RAD + np.pi, PAPER_PHASE_RAD)
    err = np.angle(np.exp(1j * (phase - expected)))
    assert np.abs(err[big]).max() < 1e-6


def test_rotational_vibration_uses_rotation_columns(robot, pose):
    axis_p, point_p = np.array([0.2, -0.4, 1.0]), np.array([0.01, -0.02, 0.08])
    amp = 2e-4  # rad
    plan = decompose_vibration(robot, pose, rotation_axis=axis_p, rotation_point=point_p, amplitude=amp,
                               frequency=20.0)
    rot0 = rpy_matrix(*pose[3:])
    w = rot0 @ axis_p / np.linalg.norm(axis_p)
    c = pose[:3] + rot0 @ point_p
    d0, arms, l0, n = legs(robot, pose[:3], rot0)
    k_ref = np.einsum("ij,ij->i", n, np.cross(w, pose[:3] - c + arms))
    np.testing.assert_allclose(plan.gains, k_ref, atol=1e-12, rtol=0)
    jac, _, _ = jacobian_ref(robot, pose)
    twist = np.concatenate([np.cross(w, pose[:3] - c), w])
    np.testing.assert_allclose(plan.gains, jac @ twist, atol=1e-12, rtol=0)
    # exact signals: rotate the platform about the axis through c, independent construction
    exact = np.empty_like(plan.exact_signals)
    for j, delta in enumerate(plan.delta):
        rd = rodrigues(w, delta)
        exact[j] = legs(robot, c + rd @ (pose[:3] - c), rd @ rot0)[2] - l0
    np.testing.assert_allclose(plan.exact_signals, exact, atol=1e-15, rtol=0)
    # second order: the difference is curvature * delta^2 / 2 with a finite-difference curvature
    h = 1e-4
    lp = legs(robot, c + rodrigues(w, h) @ (pose[:3] - c), rodrigues(w, h) @ rot0)[2]
    lm = legs(robot, c + rodrigues(w, -h) @ (pose[:3] - c), rodrigues(w, -h) @ rot0)[2]
    curvature = (lp - 2 * l0 + lm) / h**2
    pred = 0.5 * curvature * plan.delta[:, None] ** 2
    diff = plan.exact_signals - plan.linear_signals
    assert np.abs(diff - pred).max() <= 0.05 * np.abs(pred).max()
    np.testing.assert_allclose(plan.curvature, curvature, rtol=1e-4, atol=1e-6 * np.abs(curvature).max())


def test_rotation_rejects_acceleration_and_both_kinds(robot, pose):
    with pytest.raises(InvalidInputError):
        decompose_vibration(robot, pose, rotation_axis=[0, 0, 1], acceleration_g=0.3)
    with pytest.raises(InvalidInputError):
        decompose_vibration(robot, pose, direction=[0, 0, 1], rotation_axis=[0, 0, 1], amplitude=1e-4)
    with pytest.raises(InvalidInputError):
        decompose_vibration(robot, pose, direction=[0, 0, 0], amplitude=1e-6)
    with pytest.raises(InvalidInputError):
        decompose_vibration(robot, pose, amplitude=1e-6, acceleration_g=0.3)
    with pytest.raises(InvalidInputError):
        decompose_vibration(robot, pose, amplitude=1e-6, method="quadratic")
    for times in (np.zeros((4, 2)), np.array([0.0, np.nan, 0.2])):
        with pytest.raises(InvalidInputError, match="times"):
            decompose_vibration(robot, pose, amplitude=1e-6, frequency=10.0, times=times)


def test_peak_leg_acceleration_matches_finite_differences_of_the_ik(robot, pose):
    """A large lateral vibration (5 mm, where l'' delta'^2 is several % of l' delta''): each leg's peak
    acceleration equals the largest second difference of the IK leg length over one period."""
    amplitude, frequency = 5e-3, 35.0
    plan = decompose_vibration(robot, pose, direction=[1.0, 0.3, 0.2], amplitude=amplitude, frequency=frequency,
                               check_limits=False)
    t = np.linspace(0.0, 1.0 / frequency, 40001)
    dt = t[1] - t[0]
    shifted = np.tile(pose, (t.size, 1))
    shifted[:, :3] += amplitude * np.sin(2 * np.pi * frequency * t)[:, None] * plan.direction
    lengths = inverse_kinematics(robot, shifted)
    second = (lengths[2:] - 2 * lengths[1:-1] + lengths[:-2]) / dt**2
    linear_only = np.abs(plan.gains) * amplitude * (2 * np.pi * frequency) ** 2
    assert np.abs(np.abs(second).max(axis=0) / linear_only - 1).max() > 0.01  # the curvature term matters here
    np.testing.assert_allclose(plan.peak_leg_acceleration, np.abs(second).max(axis=0), rtol=2e-4)
