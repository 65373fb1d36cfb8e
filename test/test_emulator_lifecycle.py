"""hardware_emulator as a managed (lifecycle) node over real DDS: the lifecycle services drive
configure / activate / deactivate / cleanup; commands are refused when it is not active and the robot holds
its pose; a bad configuration fails the configure transition."""

from __future__ import annotations

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from lifecycle_msgs.msg import Transition
from ros_client import node_under_test
from rosgraph_msgs.msg import Clock
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from stewart_vibration import inverse_kinematics
from stewart_vibration.nodes.message_conversions import duration_msg, pose_from_msg

pytestmark = pytest.mark.integration
ARGS = ["--ros-args", "-p", "autostart:=false"]


def change(client, transition_id):
    return client.transition("hardware_emulator", transition_id)


def state(client):
    return client.lifecycle_state("hardware_emulator")


def move(robot, delta):
    """A legal 2 s leg trajectory from home by ``delta`` (m) on every strut."""
    msg = JointTrajectory(joint_names=[f"leg_{i}" for i in range(1, 7)])
    goal = inverse_kinematics(robot, robot.home_pose) + delta
    msg.points = [JointTrajectoryPoint(positions=goal.tolist(), velocities=[0.0] * 6,
                                       time_from_start=duration_msg(2.0))]
    return msg


def test_lifecycle_transitions_gate_the_commands(robot, ros_domain, tmp_path):
    with node_under_test("emulator", "stewart_vibration.nodes.hardware_emulator_node", ros_domain, tmp_path,
                         ARGS) as (proc, client):
        clock = client.subscribe("/clock", Clock)
        poses = client.subscribe("ground_truth/platform_pose", PoseStamped)
        diagnostics = client.subscribe("/diagnostics", DiagnosticArray)
        legs = client.publisher("legs/joint_trajectory", JointTrajectory)

        assert state(client) == "unconfigured"
        client.spin_for(0.5)
        assert not clock  # no physics before activate
        assert change(client, Transition.TRANSITION_CONFIGURE) and state(client) == "inactive"
        client.spin_for(0.5)
        assert not clock
        assert change(client, Transition.TRANSITION_ACTIVATE) and state(client) == "active"
        assert client.spin_until(lambda: len(poses) > 10, 20), proc.log_text()
        assert client.wait_for_subscribers("legs/joint_trajectory")

        # active: a move is followed
        legs.publish(move(robot, 0.002))
        assert client.spin_until(lambda: poses and pose_from_msg(poses[-1].pose)[2] > robot.home_pose[2] + 1e-3, 20)

        # inactive: the robot holds where it is and commands are refused with the reason
        assert change(client, Transition.TRANSITION_DEACTIVATE) and state(client) == "inactive"
        client.spin_for(0.3)
        held = pose_from_msg(poses[-1].pose)
        legs.publish(move(robot, -0.004))
        assert client.spin_until(lambda: any("inactive" in s.message and "rejected leg trajectory" in s.message
                                             for a in diagnostics for s in a.status), 10)
        client.spin_for(1.5)
        assert len(clock) > 0 and np.abs(pose_from_msg(poses[-1].pose) - held)[:3].max() < 1e-6  # physics on, held

        # active again; then cleanup releases everything (no more states), and configure works again
        assert change(client, Transition.TRANSITION_ACTIVATE)
        assert change(client, Transition.TRANSITION_DEACTIVATE)
        assert change(client, Transition.TRANSITION_CLEANUP) and state(client) == "unconfigured"
        count = len(poses)
        client.spin_for(0.5)
        assert len(poses) <= count + 5  # the last few in flight at most
        assert change(client, Transition.TRANSITION_CONFIGURE) and state(client) == "inactive"
        assert proc.alive()


def test_bad_configuration_fails_the_configure_transition(ros_domain, tmp_path):
    bad = tmp_path / "robot.yaml"
    bad.write_text("geometry: {}\n")
    with node_under_test("emulator", "stewart_vibration.nodes.hardware_emulator_node", ros_domain, tmp_path,
                         ARGS + ["-p", f"robot_config:={bad}"]) as (proc, client):
        assert not change(client, Transition.TRANSITION_CONFIGURE)
        assert state(client) == "unconfigured" and proc.alive()
        assert "configure failed" in proc.log_text()


def set_parameter(client, name: str, value):
    """The emulator's answer to a set_parameters request of one parameter (SetParametersResult)."""
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter

    request = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
    return client.call(SetParameters, "hardware_emulator/set_parameters", request).results[0]


def last_diagnostic_value(diagnostics, key: str):
    values = [kv.value for a in diagnostics for s in a.status if s.name.startswith("hardware_emulator")
              for kv in s.values if kv.key == key]
    return values[-1] if values else None


def test_reconfigure_applies_a_parameter_read_at_configure_and_the_clock_goes_on(robot, ros_domain, tmp_path):
    """cleanup -> set physics_rate_hz -> configure -> activate runs the new rate (a set while configured is
    refused, saying how); sim time goes on from where it was: /clock never goes back within the run."""
    with node_under_test("emulator", "stewart_vibration.nodes.hardware_emulator_node", ros_domain, tmp_path,
                         ARGS) as (proc, client):
        clock = client.subscribe("/clock", Clock, depth=100000)
        diagnostics = client.subscribe("/diagnostics", DiagnosticArray)
        assert set_parameter(client, "physics_rate_hz", 1500.0).successful  # unconfigured: taken
        assert change(client, Transition.TRANSITION_CONFIGURE) and change(client, Transition.TRANSITION_ACTIVATE)
        assert client.spin_until(lambda: clock and clock[-1].clock.sec >= 1, 30), proc.log_text()
        assert client.spin_until(lambda: last_diagnostic_value(diagnostics, "physics_rate_hz") == "1500.0", 10)

        refused = set_parameter(client, "physics_rate_hz", 1000.0)  # configured: refused with how to do it
        assert not refused.successful and "read at configure" in refused.reason and "cleanup" in refused.reason
        assert set_parameter(client, "watchdog_s", 0.4).successful  # a live one is taken
        assert not set_parameter(client, "autostart", True).successful  # read at start: read only

        assert change(client, Transition.TRANSITION_DEACTIVATE) and change(client, Transition.TRANSITION_CLEANUP)
        before = clock[-1].clock.sec + clock[-1].clock.nanosec * 1e-9
        assert set_parameter(client, "physics_rate_hz", 1000.0).successful
        assert change(client, Transition.TRANSITION_CONFIGURE) and change(client, Transition.TRANSITION_ACTIVATE)
        assert client.spin_until(lambda: last_diagnostic_value(diagnostics, "physics_rate_hz") == "1000.0", 10)
        assert client.spin_until(lambda: clock[-1].clock.sec + clock[-1].clock.nanosec * 1e-9 > before + 1.0, 30)
        times = np.array([c.clock.sec + c.clock.nanosec * 1e-9 for c in clock])
        assert (np.diff(times) >= 0).all(), "the clock went back"
        assert times[0] < 0.5 and before >= 1.0  # one run: it started near 0 and went on past the reconfigure
        assert proc.alive()
