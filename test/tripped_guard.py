"""A force guard that tripped, for the tests of what a trip refuses: it watched a 1 s lift of 10 mm in z from
home, its struts on the plan up to 0.4 s, while the load estimate rose through its 200 N limit (to 300 N)."""

from __future__ import annotations

import numpy as np

from stewart_vibration import inverse_kinematics
from stewart_vibration.motion.force_guard import ForceGuard
from stewart_vibration.motion.profiles import minimum_jerk


def lift_into(guard: ForceGuard, robot) -> ForceGuard:
    """Drive ``guard`` (limit at most 300 N) through the lift until it trips; returns it."""
    goal = robot.home_pose + [0, 0, 0.01, 0, 0, 0]
    l0, l1 = inverse_kinematics(robot, robot.home_pose), inverse_kinematics(robot, goal)
    guard.begin_move(0.0, 1.0, l0, l1, robot.home_pose, goal)
    times = np.arange(0.0, 0.4, 0.002)
    guard.observe_states(times, minimum_jerk(l0, l1, 1.0, times)[0])
    stamps = np.arange(0.25, 0.4, 0.002)
    wrenches = np.zeros((stamps.size, 6))
    wrenches[:, 2] = 2000.0 * (stamps - 0.25)
    assert guard.observe(stamps, wrenches, 0.4) is not None and guard.tripped
    return guard


def tripped_guard(robot) -> ForceGuard:
    """A guard (200 N, 15 N m) tripped by the lift: goals further up from where it held are refused."""
    return lift_into(ForceGuard(robot, 200.0, 15.0), robot)
