"""Launch the stewart_vibration node suite on a ROS 2 install (the same nodes and
parameters as `stewart-vibration run` in the pip world).

    ros2 launch stewart_vibration stewart_vibration.launch.py \
        [namespace:=/stewart] [real_time_factor:=1.0] [output_dir:=runs]

Parameters come from share/stewart_vibration/config/suite_params.yaml (one
file for both worlds); the node list from stewart_vibration.suite.
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from stewart_vibration.suite import DEFAULT_NAMESPACE, SUITE_NODES, SUITE_PARAMS_FILE


def generate_launch_description():
    params = os.path.join(get_package_share_directory("stewart_vibration"), "config", SUITE_PARAMS_FILE)
    namespace = LaunchConfiguration("namespace")
    overrides = {
        "hardware_emulator": {"real_time_factor": LaunchConfiguration("real_time_factor")},
        "mcap_recorder": {"output_dir": LaunchConfiguration("output_dir")},
    }
    nodes = [
        Node(
            package="stewart_vibration",
            executable=node.executable,
            name=node.name,
            namespace=namespace,
            parameters=[params, overrides.get(node.name, {})],
            output="screen",
        )
        for node in SUITE_NODES
    ]
    return LaunchDescription(
        [
            DeclareLaunchArgument("namespace", default_value=DEFAULT_NAMESPACE),
            DeclareLaunchArgument("real_time_factor", default_value="1.0"),
            DeclareLaunchArgument("output_dir", default_value="runs"),
            *nodes,
        ]
    )
