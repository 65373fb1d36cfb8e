"""The robot's outline for robot_markers (visualization.robot_outline): each leg line joins its base hinge to
its platform hinge -- as long as inverse kinematics says at that pose -- and the hinge polygons close."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration import inverse_kinematics
from stewart_vibration.kinematics.rotations import pose_to_position_quaternion
from stewart_vibration.visualization.robot_outline import robot_outline


@pytest.mark.parametrize("pose", [None, [0.004, -0.003, 0.165, 0.05, -0.04, 0.1]])
def test_each_leg_line_is_as_long_as_its_strut_and_the_polygons_close(robot, pose):
    pose = robot.home_pose if pose is None else np.asarray(pose, float)
    position, quaternion = pose_to_position_quaternion(pose)
    outline = robot_outline(robot, position, quaternion)
    ends = outline.legs.reshape(6, 2, 3)
    assert ends[:, 0] == pytest.approx(robot.base_hinges)
    assert np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1) == pytest.approx(inverse_kinematics(robot, pose), abs=1e-12)
    assert outline.platform[:6] == pytest.approx(ends[:, 1]) and outline.platform[6] == pytest.approx(ends[0, 1])
    assert outline.base[:6] == pytest.approx(robot.base_hinges) and outline.base[6] == pytest.approx(ends[0, 0])
    assert outline.hinges == pytest.approx(np.vstack([ends[:, 0], ends[:, 1]]))
    # the platform hinges keep their spacing: a rigid motion of the platform
    drawn = np.vstack([robot.platform_hinges, robot.platform_hinges[:1]])
    spacing = np.linalg.norm(np.diff(outline.platform, axis=0), axis=1)
    assert spacing == pytest.approx(np.linalg.norm(np.diff(drawn, axis=0), axis=1))
