"""Pose estimates from measured leg lengths without ROS (kinematics.pose_tracking): IK -> FK round trips, states
whose FK does not solve left out and counted, the cold start after a batch of which none solved, and a batch
FK cannot start from leaving the estimate as it was."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration import inverse_kinematics
from stewart_vibration.errors import InvalidInputError
from stewart_vibration.kinematics.pose_tracking import PoseTracker

NO_ASSEMBLY = [0.01, 0.3, 0.3, 0.3, 0.3, 0.3]  # one strut far shorter than its neighbours: no platform fits


def poses_near_home(robot, count: int = 5) -> np.ndarray:
    offsets = np.linspace(0.0, 1.0, count)[:, None] * np.array([0.004, -0.003, 0.005, 0.03, -0.02, 0.05])
    return robot.home_pose + offsets


def test_the_poses_of_measured_lengths_are_the_poses_they_were_measured_at(robot):
    tracker = PoseTracker(robot)
    assert tracker.pose is None
    poses = poses_near_home(robot)
    solved = tracker.solve(inverse_kinematics(robot, poses))
    assert solved.ok.all() and tracker.failures == 0
    np.testing.assert_allclose(solved.poses, poses, atol=1e-10)
    np.testing.assert_allclose(tracker.pose, poses[-1], atol=1e-10)  # the newest: the batch's last
    # the next batch starts at the estimate: a pose 10 mm further up is found from there
    far = poses[-1] + [0.0, 0.0, 0.01, 0.0, 0.0, 0.0]
    np.testing.assert_allclose(tracker.solve(inverse_kinematics(robot, far[None])).poses[0], far, atol=1e-10)


def test_states_that_do_not_solve_are_left_out_and_counted(robot):
    tracker = PoseTracker(robot)
    poses = poses_near_home(robot, 3)
    lengths = np.vstack([inverse_kinematics(robot, poses[:2]), NO_ASSEMBLY, inverse_kinematics(robot, poses[2:])])
    solved = tracker.solve(lengths)
    assert solved.ok.tolist() == [True, True, False, True] and tracker.failures == 1
    np.testing.assert_allclose(solved.poses, poses, atol=1e-10)
    tracker.solve(np.array([NO_ASSEMBLY, NO_ASSEMBLY]))
    assert tracker.pose is None and tracker.failures == 3  # none solved: the next batch starts from home
    home = tracker.solve(inverse_kinematics(robot, robot.home_pose[None]))
    np.testing.assert_allclose(home.poses[0], robot.home_pose, atol=1e-12)


def test_lengths_fk_cannot_start_from_leave_the_estimate_as_it_was(robot):
    tracker = PoseTracker(robot)
    tracker.solve(inverse_kinematics(robot, robot.home_pose[None]))
    before = tracker.pose.copy()
    with pytest.raises(InvalidInputError, match="> 0"):
        tracker.solve(np.array([[0.17, 0.17, -0.01, 0.17, 0.17, 0.17]]))
    assert np.array_equal(tracker.pose, before) and tracker.failures == 0
