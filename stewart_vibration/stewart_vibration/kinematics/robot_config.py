"""``load_robot``: the robot from its YAML file, read safely and checked whole (the one way a robot file is
loaded: every node, the CLI and the run summary call it).

The file is read by ``safe_yaml.load_yaml`` (regular file, size, UTF-8, alias limits), every value is
checked against its plausible range by ``robot.robot_from_dict``, and the home pose must be one the
robot can take: ``ik.check_pose`` (strokes, joint angles, conditioning, the checks of ``limits``).
"""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import ConfigError, StewartError
from ..install import default_config_dir
from ..robot import Robot, drawing_tree, robot_from_dict
from ..safe_yaml import load_yaml
from .ik import check_pose


def check_home_pose(robot: Robot, where: str) -> None:
    """ConfigError naming ``geometry.home_pose`` if the robot cannot take its own home pose.

    Args:
        robot: the robot.
        where: the file ("robot config config/robot.yaml"), for the message.

    Raises:
        ConfigError: the home pose fails ``check_pose`` (stroke, joint angle, conditioning), with its reason.
    """
    try:
        check_pose(robot, robot.home_pose)
    except StewartError as exc:
        raise ConfigError(f"{where}: 'geometry.home_pose' {robot.home_pose.tolist()} cannot be taken by this "
                          f"robot: {type(exc).__name__}: {exc}") from None


def robot_from_config(tree, source: str = "<dict>") -> Robot:
    """``robot_from_dict`` and the home pose check: a robot built from a parsed config, checked whole."""
    robot = robot_from_dict(tree, source)
    check_home_pose(robot, f"robot config {source}")
    return robot


def load_robot(path: str | os.PathLike | None = None) -> Robot:
    """Load the robot from a YAML file (default: config/robot.yaml).

    Args:
        path: the robot YAML; None = robot.yaml in ``default_config_dir()``.

    Returns:
        The Robot, every value plausible and its home pose reachable.

    Raises:
        ConfigError: one line naming the file and, where it applies, the key: a file that cannot be read
            safely (``load_yaml``), a missing, mistyped or implausible value (``robot_from_dict``), or a home
            pose the robot cannot take.
    """
    path = Path(path).expanduser() if path is not None else default_config_dir() / "robot.yaml"
    return robot_from_config(load_yaml(path, "robot config"), str(path))


def load_drawing(path: str | os.PathLike | None = None) -> Robot:
    """The robot of a robot file as drawn (``load_robot`` without a calibration's corrections): what the
    emulated robot is built from, whichever file the controller runs with."""
    path = Path(path).expanduser() if path is not None else default_config_dir() / "robot.yaml"
    return robot_from_config(drawing_tree(load_yaml(path, "robot config")), str(path))
