"""The node suite (no rclpy): which nodes make up a run, read by both the pip-world
bring-up (`stewart-vibration run`) and launch/stewart_vibration.launch.py."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SuiteNode:
    """One node of the suite: its ROS name, console script and ``python -m`` module."""

    name: str  # ROS node name (matches config/suite_params.yaml)
    executable: str  # console script (ros2 run stewart_vibration <executable>)
    module: str  # python -m module (pip world)


SUITE_NODES = [
    SuiteNode("hardware_emulator", "hardware_emulator_node", "stewart_vibration.nodes.hardware_emulator_node"),
    SuiteNode("kinematics", "kinematics_node", "stewart_vibration.nodes.kinematics_node"),
    SuiteNode("vibration_planner", "vibration_planner_node", "stewart_vibration.nodes.vibration_planner_node"),
    SuiteNode("leg_force_estimator", "leg_force_estimator_node", "stewart_vibration.nodes.leg_force_estimator_node"),
    SuiteNode("mcap_recorder", "mcap_recorder", "stewart_vibration.nodes.mcap_recorder_node"),
]
# Nodes the bring-up starts on request (`stewart-vibration run --foxglove / --ui`; launch arguments
# foxglove:=true / ui:=true): views and user interfaces over the same topics and services as any client.
OPTIONAL_NODES = {
    "foxglove": SuiteNode("foxglove_bridge", "foxglove_bridge", "stewart_vibration.nodes.foxglove_bridge_node"),
    "ui": SuiteNode("planning_ui", "planning_ui", "stewart_vibration.nodes.planning_ui_node"),
}
SUITE_PARAMS_FILE = "suite_params.yaml"  # in config/
DEFAULT_NAMESPACE = "/stewart"
