"""Batch splitting over threads: exact coverage, order, errors, same numbers as one thread."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from stewart_vibration import inverse_kinematics, load_robot
from stewart_vibration.parallel import map_row_ranges, row_ranges, worker_count


@pytest.mark.parametrize("count,parts,align", [(10, 3, 1), (100_000, 2, 8192), (8192, 4, 8192), (5, 8, 1), (1, 2, 4)])
def test_row_ranges_cover_every_row_once_on_aligned_boundaries(count, parts, align):
    ranges = row_ranges(count, parts, align)
    assert 1 <= len(ranges) <= parts
    assert ranges[0][0] == 0 and ranges[-1][1] == count
    for (_, stop), (start, _) in zip(ranges[:-1], ranges[1:]):
        assert stop == start and stop % align == 0
    assert all(stop > start for start, stop in ranges)


def test_map_row_ranges_runs_in_threads_and_keeps_order(monkeypatch):
    monkeypatch.setenv("STEWART_VIBRATION_THREADS", "2")
    assert worker_count() == 2
    seen = []

    def work(start, stop):
        seen.append(threading.current_thread().name)
        return (start, stop)

    ranges = map_row_ranges(work, 200_000, min_rows=1000, align=8192)
    assert ranges == row_ranges(200_000, 2, 8192)
    assert all(name.startswith("stewart-batch") for name in seen)
    assert map_row_ranges(work, 500, min_rows=1000) == [(0, 500)]  # small: caller's thread


def test_map_row_ranges_reraises_a_worker_error(monkeypatch):
    monkeypatch.setenv("STEWART_VIBRATION_THREADS", "2")

    def work(start, stop):
        if start > 0:
            raise ValueError(f"rows {start}:{stop}")
        return start

    with pytest.raises(ValueError, match="rows"):
        map_row_ranges(work, 100, min_rows=10)


def test_threaded_ik_equals_single_thread(monkeypatch):
    robot = load_robot()
    rng = np.random.default_rng(0)
    poses = robot.home_pose + rng.uniform(-1, 1, (150_000, 6)) * [0.02, 0.02, 0.02, 0.26, 0.26, 0.26]
    monkeypatch.setenv("STEWART_VIBRATION_THREADS", "1")
    one = inverse_kinematics(robot, poses)
    monkeypatch.setenv("STEWART_VIBRATION_THREADS", "2")
    two = inverse_kinematics(robot, poses)
    assert np.array_equal(one, two)


def test_threaded_leg_forces_equal_single_thread(monkeypatch):
    from stewart_vibration.dynamics.newton_euler import leg_forces

    robot = load_robot()
    rng = np.random.default_rng(1)
    n = 140_000  # above the threading threshold, not a multiple of the block size
    poses = robot.home_pose + rng.uniform(-1, 1, (n, 6)) * [0.01, 0.01, 0.01, 0.1, 0.1, 0.1]
    twist, accel = rng.normal(size=(n, 6)), rng.normal(size=(n, 6))
    monkeypatch.setenv("STEWART_VIBRATION_THREADS", "1")
    one = leg_forces(robot, poses, twist, accel, return_reactions=True)
    monkeypatch.setenv("STEWART_VIBRATION_THREADS", "2")
    two = leg_forces(robot, poses, twist, accel, return_reactions=True)
    for a, b in zip((one.force, one.platform_joint, one.base_joint), (two.force, two.platform_joint, two.base_joint)):
        assert np.array_equal(a, b)
