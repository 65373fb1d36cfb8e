"""joint_trajectory_controller semantics of the emulator's trajectory follower."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration import InvalidInputError
from stewart_vibration.emulation.strut_trajectory import TrajectoryFollower, build_trajectory

NAMES = [f"leg_{i}" for i in range(1, 7)]


def fd_check(follower, t0, t1, knots):
    """Velocity and acceleration against central differences, away from knots
    (a cubic spline's acceleration may jump there)."""
    t = np.linspace(t0, t1, 4001)
    p, v, a = follower.sample(t)
    dt = t[1] - t[0]
    away = np.ones(t.size, dtype=bool)
    for k in knots:
        away &= np.abs(t - k) > 2.5 * dt
    away[:2] = away[-2:] = False
    assert np.allclose(np.gradient(p, dt, axis=0)[away], v[away], atol=1e-6 * max(1, np.abs(v).max()))
    assert np.allclose(np.gradient(v, dt, axis=0)[away], a[away], atol=1e-4 * max(1, np.abs(a).max()))


@pytest.mark.parametrize("kind", ["linear", "cubic", "quintic"])
def test_passes_through_points(kind):
    rng = np.random.default_rng(0)
    times = np.array([0.5, 1.0, 1.7])
    pos = 0.17 + 0.01 * rng.normal(size=(3, 6))
    vel = 0.01 * rng.normal(size=(3, 6)) if kind != "linear" else None
    acc = 0.1 * rng.normal(size=(3, 6)) if kind == "quintic" else None
    traj = build_trajectory(NAMES, NAMES, 0.0, times, pos, vel, acc)
    follower = TrajectoryFollower(np.full(6, 0.17))
    follower.replace(traj, now=10.0)
    p, v, a = follower.sample(10.0 + times)
    assert np.allclose(p, pos, atol=1e-14)
    if vel is not None:
        assert np.allclose(v[:-1], vel[:-1], atol=1e-12)
    if acc is not None:
        assert np.allclose(a[:-1], acc[:-1], atol=1e-10)
    p_before, _, _ = follower.sample([10.0])
    assert np.allclose(p_before, 0.17)  # departs from the held state
    p_after, v_after, a_after = follower.sample([20.0])  # after the last point, the last point holds
    assert np.array_equal(p_after[0], pos[-1])
    assert np.array_equal(v_after[0], vel[-1] if vel is not None else np.zeros(6))
    assert np.array_equal(a_after[0], acc[-1] if acc is not None else np.zeros(6))
    if kind != "linear":
        fd_check(follower, 10.0, 11.7, 10.0 + times)


def test_names_in_any_order_are_reordered():
    shuffled = NAMES[::-1]
    pos = [[0.16 + 0.001 * i for i in range(6)]]
    traj = build_trajectory(shuffled, NAMES, 0.0, [1.0], pos)
    assert np.allclose(traj.positions[0], pos[0][::-1])


def test_replacement_is_continuous():
    follower = TrajectoryFollower(np.full(6, 0.17))
    first = build_trajectory(NAMES, NAMES, 0.0, [1.0], [[0.18] * 6], [[0.0] * 6], [[0.0] * 6])
    follower.replace(first, now=0.0)
    mid = follower.sample([0.5])
    second = build_trajectory(NAMES, NAMES, 0.0, [1.0], [[0.16] * 6], [[0.0] * 6], [[0.0] * 6])
    follower.replace(second, now=0.5)
    after = follower.sample([0.5, 0.5 + 1e-6])
    assert np.allclose(after[0][0], mid[0][0], atol=1e-15)  # position continuous at the switch
    assert np.allclose(after[1][0], mid[1][0], atol=1e-12)  # velocity continuous too
    assert np.allclose(follower.sample([2.0])[0], 0.16)


def test_future_start_holds_until_stamp():
    follower = TrajectoryFollower(np.full(6, 0.17))
    traj = build_trajectory(NAMES, NAMES, 5.0, [1.0], [[0.18] * 6])
    follower.replace(traj, now=1.0)
    assert np.allclose(follower.sample([4.9])[0], 0.17)
    assert np.allclose(follower.sample([6.0])[0], 0.18)
    assert not follower.finished(5.5) and follower.finished(6.0)


@pytest.mark.parametrize(
    "names,times,pos,match",
    [
        (NAMES[:5], [1.0], [[0.17] * 5], "joint names"),
        (NAMES[:5] + ["leg_1"], [1.0], [[0.17] * 6], "joint names"),
        (NAMES[:5] + ["foo"], [1.0], [[0.17] * 6], "joint names"),
        (NAMES, [1.0, 1.0], [[0.17] * 6] * 2, "strictly increasing"),
        (NAMES, [2.0, 1.0], [[0.17] * 6] * 2, "strictly increasing"),
        (NAMES, [], [], "no points"),
        (NAMES, [1.0], [[0.17] * 5], "6 positions"),
        (NAMES, [1.0], [[float("nan")] * 6], "non-finite"),
        (NAMES, [float("nan")], [[0.17] * 6], "strictly increasing"),
        (NAMES, [1e308], [[0.17] * 6], "exceeds"),  # hypothesis, CI: overflowed into NaN strut lengths
    ],
)
def test_malformed_trajectories_are_rejected(names, times, pos, match):
    with pytest.raises(InvalidInputError, match=match):
        build_trajectory(names, NAMES, 0.0, times, pos)
