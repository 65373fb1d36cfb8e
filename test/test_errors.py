"""Typed errors for bad input: every error class, with leg and sample."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from stewart_vibration import (
    ConfigError,
    InvalidInputError,
    JointLimitError,
    SingularPoseError,
    StrokeLimitError,
    UnreachablePoseError,
    check_pose,
    condition_number,
    forward_kinematics,
    inverse_kinematics,
    jacobian,
    load_robot,
    pose_from_position_quaternion,
)
from stewart_vibration.install import default_config_dir
from stewart_vibration.robot import robot_from_dict


def config_tree():
    return yaml.safe_load((default_config_dir() / "robot.yaml").read_text())


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_pose(robot, bad):
    poses = np.tile(robot.home_pose, (5, 1))
    poses[3, 4] = bad
    with pytest.raises(InvalidInputError, match="sample 3"):
        inverse_kinematics(robot, poses)
    with pytest.raises(InvalidInputError):
        jacobian(robot, poses)


@pytest.mark.parametrize("shape", [(5,), (7,), (3, 5), ()])
def test_wrong_pose_shape(robot, shape):
    with pytest.raises(InvalidInputError, match="expected shape"):
        inverse_kinematics(robot, np.zeros(shape))


def test_non_numeric_pose(robot):
    with pytest.raises(InvalidInputError, match="not numeric"):
        inverse_kinematics(robot, ["a"] * 6)


def test_stroke_limit_names_leg_and_excess(robot):
    pose = robot.home_pose.copy()
    pose[2] += 0.09  # everything too long
    with pytest.raises(StrokeLimitError) as info:
        inverse_kinematics(robot, pose)
    err = info.value
    lengths = inverse_kinematics(robot, pose, check_limits=False)
    assert err.leg == int(np.argmax(lengths > robot.limits.stroke_max)) + 1
    assert err.excess == pytest.approx(lengths[err.leg - 1] - robot.limits.stroke_max)
    assert f"leg {err.leg}" in str(err) and "mm" in str(err)
    assert isinstance(err, UnreachablePoseError)


def test_stroke_limit_below_minimum(robot):
    pose = robot.home_pose.copy()
    pose[2] -= 0.10
    with pytest.raises(StrokeLimitError, match="below the minimum"):
        inverse_kinematics(robot, pose)


def test_stroke_limit_in_large_batch_reports_sample(robot):
    poses = np.tile(robot.home_pose, (20_000, 1))
    poses[12_345, 0] = 0.2
    with pytest.raises(StrokeLimitError) as info:
        inverse_kinematics(robot, poses)
    assert info.value.sample == 12_345
    assert "sample 12345" in str(info.value)


def test_joint_limit(robot):
    tree = config_tree()
    tree["limits"]["universal_joint_max_deg"] = 25.0  # home legs lean ~23 deg
    strict = robot_from_dict(tree)
    pose = strict.home_pose.copy()
    pose[0] += 0.02
    with pytest.raises(JointLimitError, match="universal") as info:
        inverse_kinematics(strict, pose)
    assert 1 <= info.value.leg <= 6 and info.value.value > info.value.limit


def test_unreachable_below_base(robot):
    pose = robot.home_pose.copy()
    pose[2] = -0.16
    with pytest.raises(UnreachablePoseError, match="not above the base"):
        inverse_kinematics(robot, pose)
    # exactly in the base plane (hinges at z = 0 in both frames): not above either
    pose[2] = 0.0
    with pytest.raises(UnreachablePoseError, match="not above the base"):
        inverse_kinematics(robot, pose)


def test_near_singular_pose(robot):
    tree = config_tree()
    tree["limits"]["condition_number_max"] = 3.0  # below home's value
    strict = robot_from_dict(tree)
    with pytest.raises(SingularPoseError, match="condition number"):
        check_pose(strict, strict.home_pose)
    assert check_pose(robot, robot.home_pose).shape == (6,)
    # in a batch, the error names the first sample over the limit and its value
    poses = robot.home_pose + np.array([[0, 0, 0, 0, 0, 0], [0.01, 0, 0, 0.1, 0, 0], [0, 0, 0, 0, 0, 0.05],
                                        [-0.01, 0.01, 0, 0, -0.1, 0]])
    cond = condition_number(robot, poses)
    ranked = np.sort(cond)
    tree["limits"]["condition_number_max"] = float(0.5 * (ranked[-1] + ranked[-2]))
    with pytest.raises(SingularPoseError) as info:
        check_pose(robot_from_dict(tree), poses)
    assert info.value.sample == int(np.argmax(cond)) != 0 and info.value.value == pytest.approx(cond.max())


def test_fk_bad_lengths(robot):
    with pytest.raises(InvalidInputError):
        forward_kinematics(robot, [0.17] * 5)
    with pytest.raises(InvalidInputError):
        forward_kinematics(robot, [0.17, 0.17, np.nan, 0.17, 0.17, 0.17])
    with pytest.raises(InvalidInputError, match="> 0"):
        forward_kinematics(robot, [0.17, 0.17, -0.17, 0.17, 0.17, 0.17])
    with pytest.raises(StrokeLimitError) as info:
        forward_kinematics(robot, [0.17, 0.17, 0.17, 0.30, 0.17, 0.17])
    assert info.value.leg == 4


def test_non_unit_quaternion():
    with pytest.raises(InvalidInputError, match="unit quaternion"):
        pose_from_position_quaternion([0, 0, 0.16], [0, 0, 0, 2.0])


def test_config_errors(tmp_path):
    with pytest.raises(ConfigError, match="cannot read"):
        load_robot(tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("geometry: [unclosed")
    with pytest.raises(ConfigError, match="invalid YAML"):
        load_robot(bad)
    tree = config_tree()
    del tree["limits"]["stroke_max_m"]
    with pytest.raises(ConfigError, match="limits.stroke_max_m"):
        robot_from_dict(tree)
    tree = config_tree()
    tree["geometry"]["base"]["angles_deg"] = [0, 1, 2]
    with pytest.raises(ConfigError, match="'geometry.base.angles_deg' must be a list of 6 numbers"):
        robot_from_dict(tree)
    tree = config_tree()
    tree["limits"]["stroke_min_m"] = 0.3
    with pytest.raises(ConfigError, match="'limits.stroke_min_m' 0.3 must be < 'limits.stroke_max_m' 0.25"):
        robot_from_dict(tree)
    tree = config_tree()
    tree["inertia"]["platform"]["mass_kg"] = -1
    with pytest.raises(ConfigError, match=r"'inertia.platform.mass_kg' = -1 is outside its plausible range \(0, 1"):
        robot_from_dict(tree)
