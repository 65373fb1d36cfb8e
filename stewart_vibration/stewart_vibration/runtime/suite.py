"""The node suite (no rclpy): which nodes make up a run, read by both the pip-world
bring-up (`stewart-vibration run`) and launch/stewart_vibration.launch.py."""

from __future__ import annotations

import re
from dataclasses import dataclass


@dataclass(frozen=True)
class SuiteNode:
    """One node of the suite: its ROS name, console script and ``python -m`` module."""

    name: str  # ROS node name (matches config/suite_params.yaml)
    executable: str  # console script (ros2 run stewart_vibration <executable>)
    module: str  # python -m module (pip world)
    robot_config: bool = True  # it reads robot.yaml (takes the robot_config parameter)


SUITE_NODES = [
    SuiteNode("hardware_emulator", "hardware_emulator_node", "stewart_vibration.nodes.hardware_emulator_node"),
    SuiteNode("kinematics", "kinematics_node", "stewart_vibration.nodes.kinematics_node"),
    SuiteNode("vibration_planner", "vibration_planner_node", "stewart_vibration.nodes.vibration_planner_node"),
    SuiteNode("leg_force_estimator", "leg_force_estimator_node", "stewart_vibration.nodes.leg_force_estimator_node"),
    SuiteNode("mcap_recorder", "mcap_recorder", "stewart_vibration.nodes.mcap_recorder_node", robot_config=False),
]
# Nodes the bring-up starts on request (`stewart-vibration run --foxglove / --ui`; launch arguments
# foxglove:=true / ui:=true): views and user interfaces over the same topics and services as any client.
OPTIONAL_NODES = {
    "foxglove": SuiteNode("foxglove_bridge", "foxglove_bridge", "stewart_vibration.nodes.foxglove_bridge_node"),
    "ui": SuiteNode("planning_ui", "planning_ui", "stewart_vibration.nodes.planning_ui_node"),
}
SUITE_PARAMS_FILE = "suite_params.yaml"  # in config/
DEFAULT_NAMESPACE = "/stewart"
# ROS allows 245 characters; the suite's topic and service names add up to ~60 to it, and rcl caps a full
# name at 247, so a run's namespace is kept well below.
NAMESPACE_MAX_LENGTH = 100
_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def namespace_reason(namespace: str) -> str | None:
    """Why ``namespace`` cannot be the run's ROS namespace (rmw's rules: absolute, tokens of letters, digits and
    '_' not starting with a digit, single '/' between them, no trailing '/'; at most NAMESPACE_MAX_LENGTH
    characters), or None if it can.

    Args:
        namespace: the namespace as typed (e.g. "/stewart").

    Returns:
        The reason, or None.
    """
    if not namespace.startswith("/"):
        return f"{namespace!r} must be absolute (start with '/'), e.g. /stewart"
    if len(namespace) > NAMESPACE_MAX_LENGTH:
        return f"{len(namespace)} characters, at most {NAMESPACE_MAX_LENGTH}"
    if namespace == "/":
        return None
    for token in namespace[1:].split("/"):
        if not _TOKEN.fullmatch(token):
            what = ("an empty part ('//' or a trailing '/')" if not token
                    else f"the part {token!r}: only letters, digits and '_', not starting with a digit")
            return f"{namespace!r} has {what}"
    return None
