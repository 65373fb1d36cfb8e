"""Launch the stewart_vibration node suite on a ROS 2 install (the same nodes and
parameters as `stewart-vibration run` in the pip world).

    ros2 launch stewart_vibration stewart_vibration.launch.py \
        [namespace:=/stewart] [real_time_factor:=1.0] [output_dir:=DIR] [foxglove:=true] [ui:=true] \
        [tissue_config:=/path/to/tissue.yaml] [robot_config:=/path/to/robot.yaml]

Parameters come from share/stewart_vibration/config/suite_params.yaml (one
file for both worlds); the node list from stewart_vibration.runtime.suite. DDS: like
the pip-world bring-up, loopback only by default (share/stewart_vibration/config/
fastdds_localhost.xml); STEWART_DDS_PROFILE=multihost (or a profile path) in the
launching shell selects another (docs/security.md). The hardware emulator is a
lifecycle node: this file configures and then activates it (`ros2 lifecycle get
/stewart/hardware_emulator`).
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import (
    DeclareLaunchArgument,
    EmitEvent,
    RegisterEventHandler,
    SetEnvironmentVariable,
    UnsetEnvironmentVariable,
)
from launch.conditions import IfCondition
from launch.events import matches_action
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import LifecycleNode, Node
from launch_ros.event_handlers import OnStateTransition
from launch_ros.events.lifecycle import ChangeState
from launch_ros.parameter_descriptions import ParameterValue
from lifecycle_msgs.msg import Transition

from stewart_vibration.runtime.processes import DDS_PROFILE_ENV, dds_environment
from stewart_vibration.runtime.suite import DEFAULT_NAMESPACE, OPTIONAL_NODES, SUITE_NODES, SUITE_PARAMS_FILE

LAUNCH_ARGUMENTS = (  # (name, default, what it does: `ros2 launch -s`)
    ("namespace", DEFAULT_NAMESPACE, "ROS namespace of every node and topic"),
    ("real_time_factor", "1.0", "hardware emulator: sim seconds per wall second (0 = fastest)"),
    ("output_dir", "", "MCAP recorder bag folder ('' = a new runs/run_<stamp>/ here)"),
    ("foxglove", "false", "also start the Foxglove WebSocket bridge (127.0.0.1:8765)"),
    ("ui", "false", "also start the planning UI (its address and token are logged)"),
    ("tissue_config", "", "soft-tissue YAML for the emulator and kinematics ('' = none)"),
    ("robot_config", "", "robot YAML for every node ('' = config/robot.yaml)"),
)

def generate_launch_description():
    config_dir = os.path.join(get_package_share_directory("stewart_vibration"), "config")
    params = os.path.join(config_dir, SUITE_PARAMS_FILE)
    # Set before any node starts, so every node's participant gets the profile.
    dds = [
        UnsetEnvironmentVariable(name) if value is None else SetEnvironmentVariable(name, value)
        for name, value in dds_environment(os.environ.get(DDS_PROFILE_ENV), config_dir).items()
    ]
    namespace = LaunchConfiguration("namespace")
    # soft tissue on the platform ('' = none): the emulator applies it, kinematics checks targets against it
    tissue = ParameterValue(LaunchConfiguration("tissue_config"), value_type=str)
    # the robot every node reads ('' = config/robot.yaml), like --robot of the bring-up
    robot = ParameterValue(LaunchConfiguration("robot_config"), value_type=str)
    overrides = {
        "hardware_emulator": {"real_time_factor": LaunchConfiguration("real_time_factor"), "autostart": False,
                              "tissue_config": tissue},
        "kinematics": {"tissue_config": tissue},
        # '' = the recorder makes its own run folder runs/run_<stamp>/ (a bag directory) under the working directory
        "mcap_recorder": {"output_dir": ParameterValue(LaunchConfiguration("output_dir"), value_type=str)},
    }

    def parameters(spec):
        return [params, {**overrides.get(spec.name, {}), **({"robot_config": robot} if spec.robot_config else {})}]

    nodes = []
    for node in SUITE_NODES:
        kind = LifecycleNode if node.name == "hardware_emulator" else Node
        nodes.append(kind(
            package="stewart_vibration",
            executable=node.executable,
            name=node.name,
            namespace=namespace,
            parameters=parameters(node),
            output="screen",
        ))
    optional = [
        Node(package="stewart_vibration", executable=spec.executable, name=spec.name, namespace=namespace,
             parameters=parameters(spec), output="screen", condition=IfCondition(LaunchConfiguration(key)))
        for key, spec in OPTIONAL_NODES.items()
    ]
    # the hardware emulator is a managed node: configure it at start, activate it once it is inactive
    emulator = next(n for n, spec in zip(nodes, SUITE_NODES, strict=True) if spec.name == "hardware_emulator")
    lifecycle = [
        RegisterEventHandler(OnStateTransition(
            target_lifecycle_node=emulator, goal_state="inactive",
            entities=[EmitEvent(event=ChangeState(lifecycle_node_matcher=matches_action(emulator),
                                                  transition_id=Transition.TRANSITION_ACTIVATE))])),
        EmitEvent(event=ChangeState(lifecycle_node_matcher=matches_action(emulator),
                                    transition_id=Transition.TRANSITION_CONFIGURE)),
    ]
    return LaunchDescription(
        [
            *(DeclareLaunchArgument(name, default_value=default, description=description)
              for name, default, description in LAUNCH_ARGUMENTS),
            *dds,
            *nodes,
            *optional,
            *lifecycle,
        ]
    )
