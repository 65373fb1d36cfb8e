"""Superposition: round trips, exact FK vs linear, classification, the paper's naive sum."""

from __future__ import annotations

import numpy as np
import pytest
from vibration_reference import jacobian_ref, line_angle, rpy_matrix

from stewart_vibration import decompose_vibration, inverse_kinematics, superpose_vibration
from stewart_vibration.errors import InvalidInputError
from stewart_vibration.paper import PAPER_AMPLITUDE_M, PAPER_FREQUENCY_HZ, PAPER_PHASE_RAD, paper_pose
from stewart_vibration.vibration import classify_motion


@pytest.fixture(scope="module")
def pose(robot):
    return paper_pose(robot)


def legs_for_motion(jac, a, b=None):
    """Leg table for the platform motion a sin(w t) + b cos(w t) ([dp; dphi] 6-vectors), linear map J."""
    ja = jac @ a
    jb = np.zeros(6) if b is None else jac @ b
    return np.hypot(ja, jb), np.arctan2(jb, ja)


@pytest.mark.parametrize("direction", [None, [1.0, 0.0, 0.0], [0.3, -0.7, 0.2]])
@pytest.mark.parametrize("accel", [None, 0.3])
def test_round_trip_decompose_superpose(robot, pose, direction, accel):
    amp = PAPER_AMPLITUDE_M if accel is None else None
    freq = PAPER_FREQUENCY_HZ if accel is None else 35.0
    plan = decompose_vibration(robot, pose, direction=direction, amplitude=amp, acceleration_g=accel,
                               frequency=freq, phase=PAPER_PHASE_RAD)
    result = superpose_vibration(robot, pose, plan, times=plan.times)
    u = plan.direction
    a = plan.amplitude
    lin = result.classification_linear
    assert lin.kind == "line"
    assert line_angle(lin.principal_direction, u) < 1e-6
    assert lin.translation_amplitude == pytest.approx(0.5 * np.ptp(plan.delta), rel=1e-9)  # half the sampled swing
    assert np.abs(result.linear[:, 3:]).max() < 1e-12 * a
    # linear motion is exactly u delta(t)
    np.testing.assert_allclose(result.linear[:, :3], np.outer(plan.delta, u), atol=1e-12 * a)
    # exact: within the second-order bound. dx ~ u delta - e delta^2 with e = J^-1 c, c_i = (1 - k_i^2) / (2 l_i)
    jac, lengths, n = jacobian_ref(robot, pose)
    k = n @ u
    e = np.linalg.solve(jac, (1 - k**2) / (2 * lengths))
    ex = result.classification_exact
    assert ex.kind == "line"
    assert line_angle(ex.principal_direction, u) <= max(np.linalg.norm(e[:3]) * a, 1e-9)
    rot_pred = np.linalg.norm(e[3:]) * a**2 / 2  # peak of |e_r (delta^2 - mean)|
    assert ex.rotation_amplitude == pytest.approx(rot_pred, rel=0.05)
    # exact minus linear follows the second-order term -e (delta^2 - <delta^2>) pointwise
    d2 = plan.delta**2
    pred = -np.outer(d2, e)
    diff = result.exact - result.linear
    assert np.abs(diff - pred).max() <= 0.05 * np.abs(pred).max()
    # FK really solved the leg lengths (independent IK of the exact poses)
    lengths_fk = inverse_kinematics(robot, result.poses)
    np.testing.assert_allclose(lengths_fk, lengths + result.leg_changes, atol=1e-14, rtol=0)


def test_round_trip_rotation(robot, pose):
    plan = decompose_vibration(robot, pose, rotation_axis=[0, 0, 1], rotation_point=[0, 0, 0.08],
                               amplitude=3e-4, frequency=20.0)
    result = superpose_vibration(robot, pose, plan, times=plan.times)
    w = plan.direction
    dphi = result.linear[:, 3:]
    np.testing.assert_allclose(dphi, np.outer(plan.delta, w), atol=1e-14)
    c = pose[:3] + rpy_matrix(*pose[3:]) @ np.array([0, 0, 0.08])
    np.testing.assert_allclose(result.linear[:, :3], np.outer(plan.delta, np.cross(w, pose[:3] - c)), atol=1e-15)
    assert result.classification.rotational_ratio > 1.0


def test_fig7a_different_frequencies_lissajous(robot, pose):
    table = np.column_stack([np.full(6, 20e-6), [1.0, 2.0, 3.0, 4.0, 5.0, 6.0], np.zeros(6)])
    result = superpose_vibration(robot, pose, table)
    assert result.classification_linear.kind == "lissajous"
    assert result.classification_exact.kind == "lissajous"
    assert result.classification.period == pytest.approx(1.0)
    table[:, 1] = [1.0, np.sqrt(2), np.sqrt(3), np.sqrt(5), np.pi, np.e]
    result = superpose_vibration(robot, pose, table, duration=4.0)
    assert result.classification.kind == "non-periodic"
    assert not result.classification.periodic


def test_fig7b_different_phases_ellipse(robot, pose):
    table = np.column_stack([np.full(6, 20e-6), np.full(6, 5.0), np.arange(6) * np.pi / 3])
    result = superpose_vibration(robot, pose, table)
    cls = result.classification_exact
    assert cls.kind == "ellipse"
    # linear motion is planar: normal = a_t x b_t from the J^-1 of the sin and cos parts (independent solve)
    jac, _, _ = jacobian_ref(robot, pose)
    a = np.linalg.solve(jac, 20e-6 * np.cos(table[:, 2]))[:3]
    b = np.linalg.solve(jac, 20e-6 * np.sin(table[:, 2]))[:3]
    assert line_angle(result.classification_linear.plane_normal, np.cross(a, b)) < 1e-9
    assert result.classification_linear.planarity < 1e-9


def test_fig7c_different_amplitudes_line_with_rocking(robot, pose):
    amps = np.array([10, 20, 30, 40, 50, 60]) * 1e-6
    table = np.column_stack([amps, np.full(6, 5.0), np.zeros(6)])
    result = superpose_vibration(robot, pose, table)
    cls = result.classification_exact
    assert cls.kind == "line"
    jac, _, _ = jacobian_ref(robot, pose)
    screw = np.linalg.solve(jac, amps)
    assert line_angle(result.classification_linear.principal_direction, screw[:3]) < 1e-9
    assert line_angle(cls.principal_direction, screw[:3]) < 1e-3
    # not a pure translation: it rocks (rotation content comparable to the translation)
    assert cls.rotational_ratio > 0.05
    assert cls.rotation_amplitude == pytest.approx(np.linalg.norm(screw[3:]), rel=1e-3)


@pytest.mark.parametrize("seed", range(8))
def test_random_cases_with_known_answers(robot, pose, seed):
    rng = np.random.default_rng(seed)
    jac, _, _ = jacobian_ref(robot, pose)
    scale = np.array([1, 1, 1, 10, 10, 10]) * 1e-5  # ~10 um and ~100 urad
    freq = rng.uniform(2.0, 20.0)
    # line: platform motion s sin(w t + phi) for a random screw s
    s = rng.normal(size=6) * scale
    amps, phases = legs_for_motion(jac, s)
    table = np.column_stack([amps, np.full(6, freq), phases + 0.7])
    cls = superpose_vibration(robot, pose, table).classification
    assert cls.kind == "line"
    assert line_angle(cls.principal_direction, s[:3]) < 1e-3
    # ellipse: a sin + b cos with b_t far from parallel to a_t
    a, b = rng.normal(size=6) * scale, rng.normal(size=6) * scale
    perp = np.cross(a[:3], rng.normal(size=3))
    b[:3] = 0.7 * np.linalg.norm(a[:3]) * perp / np.linalg.norm(perp)
    amps, phases = legs_for_motion(jac, a, b)
    table = np.column_stack([amps, np.full(6, freq), phases])
    cls = superpose_vibration(robot, pose, table).classification
    assert cls.kind == "ellipse"
    assert line_angle(cls.plane_normal, np.cross(a[:3], b[:3])) < 1e-3
    # Lissajous: legs 1-3 at f, legs 4-6 at 2 f or 3/2 f with random amplitudes
    ratio = rng.choice([2.0, 1.5, 3.0])
    table = np.column_stack([rng.uniform(5e-6, 30e-6, 6), [freq] * 3 + [ratio * freq] * 3, rng.uniform(0, 6, 6)])
    cls = superpose_vibration(robot, pose, table).classification
    assert cls.kind == "lissajous"
    expected_period = {2.0: 1 / freq, 1.5: 2 / freq, 3.0: 1 / freq}[ratio]
    assert cls.period == pytest.approx(expected_period, rel=1e-9)


def test_still_when_no_leg_moves(robot, pose):
    table = np.column_stack([np.zeros(6), np.full(6, 5.0), np.zeros(6)])
    result = superpose_vibration(robot, pose, table)
    assert result.classification.kind == "still"
    assert result.classification.rotation_amplitude < 1e-20  # exact FK: round-off only
    lin = result.classification_linear  # exactly zero motion: no rotation either, ratio 0 (not inf)
    assert lin.kind == "still" and lin.translation_amplitude == 0 and lin.rotation_amplitude == 0
    assert lin.rotational_ratio == 0.0


def test_two_incommensurate_frequencies_are_not_periodic():
    """5 Hz and 5 sqrt(2) Hz never repeat: no common period, not a Lissajous figure."""
    t = np.linspace(0, 2, 400)
    f = np.array([5.0, 5.0 * np.sqrt(2.0)])
    w = 2 * np.pi * f
    x = np.column_stack([np.sin(w[0] * t), np.sin(w[1] * t), 0.3 * np.cos(w[0] * t)])
    cls = classify_motion(1e-5 * x, f)
    assert not cls.periodic and cls.period is None and cls.kind == "non-periodic"
    rational = classify_motion(1e-5 * x, [5.0, 7.5])  # the same samples said to be at 5 and 7.5 Hz: period 0.4 s
    assert rational.periodic and rational.kind == "lissajous" and rational.period == pytest.approx(0.4, rel=1e-12)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_principal_direction_sign_is_fixed(sign):
    """The direction of a line is reported with its largest component positive, whichever way it was given."""
    u = sign * np.array([0.3, -0.9, 0.2]) / np.linalg.norm([0.3, -0.9, 0.2])
    t = np.linspace(0, 1, 50, endpoint=False)
    cls = classify_motion(np.outer(np.sin(2 * np.pi * t), u))
    assert cls.kind == "line"
    np.testing.assert_allclose(cls.principal_direction, [-0.3, 0.9, -0.2] / np.linalg.norm([0.3, -0.9, 0.2]),
                               rtol=0, atol=1e-12)


def test_naive_sum_is_the_paper_formula_and_is_wrong(robot, pose):
    plan = decompose_vibration(robot, pose, amplitude=PAPER_AMPLITUDE_M, frequency=PAPER_FREQUENCY_HZ,
                               phase=PAPER_PHASE_RAD)
    result = superpose_vibration(robot, pose, plan, times=plan.times)
    _, _, n = jacobian_ref(robot, pose)
    u = plan.direction
    np.testing.assert_allclose(result.naive, np.outer(plan.delta, n.T @ (n @ u)), atol=1e-20)
    err = result.naive_error()
    naive_dir = n.T @ (n @ u)
    assert err["length_ratio"] == pytest.approx(np.linalg.norm(naive_dir), rel=1e-6)
    assert err["angle_rad"] == pytest.approx(line_angle(naive_dir, u), abs=1e-9)
    assert err["length_ratio"] > 1.5 and err["angle_rad"] > np.radians(5)  # visibly wrong here


def test_linear_method_skips_fk_and_classify_validates(robot, pose):
    table = np.column_stack([np.full(6, 5e-6), np.full(6, 5.0), np.zeros(6)])
    result = superpose_vibration(robot, pose, table, method="linear")
    assert result.exact is None and result.classification is result.classification_linear
    with pytest.raises(InvalidInputError):
        classify_motion(np.zeros((10, 4)))
    with pytest.raises(InvalidInputError):
        superpose_vibration(robot, pose, np.zeros((5, 3)))


def test_naive_comparison_is_about_the_motion_not_where_it_happens():
    """compare_naive measures the principal axes and sizes of the motions about their own means: moving
    either trajectory by a constant offset changes nothing (a direction of 1 along x vs 2 along x+y:
    length ratio 1/(2 sqrt 2), 45 deg)."""
    from stewart_vibration.vibration.superpose import compare_naive

    s = np.sin(np.linspace(0.0, 2 * np.pi, 101))[:, None]
    naive, reference = s * [1.0, 0.0, 0.0], s * [2.0, 2.0, 0.0]
    for offset_a, offset_b in (([0, 0, 0], [0, 0, 0]), ([0.3, -0.2, 5.0], [-1.0, 4.0, 0.5])):
        out = compare_naive(naive + offset_a, reference + offset_b)
        assert out["length_ratio"] == pytest.approx(1 / (2 * np.sqrt(2)), rel=1e-12)
        assert out["angle_rad"] == pytest.approx(np.pi / 4, rel=1e-12)
