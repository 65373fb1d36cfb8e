"""kinematics' move_to_pose action over DDS, from this test's process as a user's client: the real
hardware_emulator, kinematics and leg_force_estimator on sim time.

- a move to the paper's pose reports feedback at >= 10 Hz (wall time) and succeeds with the residual error of
  the controller's pose estimate, which the ground truth confirms;
- a cancel mid-move ends CANCELED, the platform at rest short of the target, every strut within the
  acceleration limit all the way (second differences of the 500 Hz states);
- the robot's own e-stop during a move ends the goal EMERGENCY_STOPPED; a goal while the e-stop is latched is
  refused by the robot (ESTOP_LATCHED); a goal sent while the reset brings the robot home waits until the
  struts stop and then succeeds, within the acceleration limit (a second one meanwhile is BUSY);
- refusals before anything moves carry their codes (a second goal: BUSY; a bad frame: UNKNOWN_FRAME).
"""

from __future__ import annotations

import numpy as np
import pytest
from ros_client import RosTestClient
from std_srvs.srv import Trigger
from test_emulator_safety_dds import ACCEL_TOL, Recorder, second_differences

from stewart_vibration import inverse_kinematics
from stewart_vibration.nodes.move_messages import MOVE_ACTION
from stewart_vibration.paper import paper_pose
from stewart_vibration.runtime.processes import ros_environment, start_python_module
from stewart_vibration_interfaces.action import MoveToPose

pytestmark = pytest.mark.integration
SIM = ["--ros-args", "-p", "use_sim_time:=true"]


@pytest.fixture(scope="module")
def suite(tmp_path_factory, module_ros_domain):
    log_dir = tmp_path_factory.mktemp("move_action_logs")
    env = ros_environment(module_ros_domain)
    procs, client = [], None
    try:
        procs = [
            start_python_module("emulator", "stewart_vibration.nodes.hardware_emulator_node",
                                ["--ros-args", "-p", "real_time_factor:=1", "-p", "lockstep:=true"], env, log_dir),
            start_python_module("kinematics", "stewart_vibration.nodes.kinematics_node", SIM, env, log_dir),
            start_python_module("estimator", "stewart_vibration.nodes.leg_force_estimator_node", SIM, env, log_dir),
        ]
        client = RosTestClient()
        rec = Recorder(client)
        assert client.spin_until(lambda: len(rec.states) > 20 and rec.status, 90), logs(procs)
        assert client.action_server_ready(MoveToPose, MOVE_ACTION, 60), logs(procs)
        yield procs, client, rec
    finally:
        if client is not None:
            client.close()
        for proc in procs:
            proc.stop()


def logs(procs) -> str:
    return "\n".join(f"--- {p.name}\n{p.log_text()[-3000:]}" for p in procs)


def back_home(client, robot, procs) -> None:
    goal = client.move(robot.home_pose)
    assert goal.outcome(120)[0] == "SUCCEEDED", logs(procs)


def test_a_move_to_the_paper_pose_reports_feedback_and_succeeds_with_its_residual_error(robot, suite):
    procs, client, rec = suite
    target = paper_pose(robot)
    goal = client.move(target)
    name, message = goal.outcome(120)
    assert name == "SUCCEEDED", (message, logs(procs))
    assert goal.status() == 4
    result = goal.result()
    assert result.position_error_m <= 1e-4 and result.angle_error_rad <= 1e-3, result
    assert result.duration_s > 0.5 and result.peak_force_n >= 0.0
    # the ground truth confirms the residual (the ideal robot: the estimate is the truth)
    truth = rec.true_poses(rec.now() - 0.05)[-1]
    assert np.abs(truth[:3] - target[:3]).max() < 1e-4 and np.abs(truth[3:] - target[3:]).max() < 1e-3
    # feedback at >= 10 Hz of wall time for as long as the goal ran, its progress from 0 to 1
    arrivals = goal.feedback_times
    span = arrivals[-1] - arrivals[0]
    assert len(arrivals) >= 10 * span and span > 0.5, (len(arrivals), span)
    assert np.diff(arrivals).max() < 0.5, "a feedback gap of half a second"
    progress = [f.feedback.progress for f in goal.feedback]
    assert progress[0] < 0.2 and progress[-1] > 0.9, progress
    pose = goal.feedback[-1].feedback.pose_estimate.position
    assert abs(pose.z - target[2]) < 2e-3
    back_home(client, robot, procs)


def test_a_cancel_mid_move_stops_short_within_the_acceleration_limit(robot, suite):
    procs, client, rec = suite
    target = robot.home_pose + np.array([0.0, 0.0, 0.02, 0.0, 0.0, 0.0])
    begin = rec.now()
    goal = client.move(target, speed_scale=0.9)
    assert client.spin_until(lambda: goal.feedback and goal.feedback[-1].feedback.progress > 0.3, 60), logs(procs)
    goal.cancel()
    name, message = goal.outcome(60)
    assert name == "CANCELED" and goal.status() == 5, (name, message, logs(procs))
    end = rec.now()
    client.spin_for(0.3)
    stamps, pos, _ = rec.series(begin, np.inf)
    accel = second_differences(stamps, pos[:, :6])
    assert accel.size and accel.max() <= robot.limits.strut_acceleration_max + ACCEL_TOL, accel.max()
    final = rec.series(end - 0.05, end)[1][:, :6]
    assert np.abs(np.diff(final, axis=0)).max() / 0.002 < 1e-3, "not at rest when the goal ended CANCELED"
    short = np.abs(final[-1] - inverse_kinematics(robot, target)).max()
    assert short > 1e-3, short  # it stopped short of the target
    back_home(client, robot, procs)


def test_the_robots_estop_ends_the_goal_and_a_goal_while_it_is_latched_is_refused(robot, suite):
    procs, client, rec = suite
    target = robot.home_pose + np.array([0.01, 0.0, 0.01, 0.0, 0.0, 0.0])
    goal = client.move(target)
    # far enough out that the way home after the reset takes a while
    assert client.spin_until(lambda: goal.feedback and goal.feedback[-1].feedback.progress > 0.5, 60), logs(procs)
    assert client.call(Trigger, "hardware_emulator/emergency_stop", Trigger.Request()).success
    assert goal.outcome(60)[0] == "EMERGENCY_STOPPED", logs(procs)
    latched = client.move(robot.home_pose)
    name, message = latched.outcome(60)
    assert name == "ESTOP_LATCHED", (name, message)
    assert client.call(Trigger, "hardware_emulator/reset", Trigger.Request()).success

    def strut_speed() -> float:  # m/s, the fastest strut over the last 50 ms of states
        stamps, pos, _ = rec.series(rec.now() - 0.05, np.inf)
        return float(np.abs(pos[-1, :6] - pos[0, :6]).max() / (stamps[-1] - stamps[0])) if len(stamps) > 5 else 0.0

    assert client.spin_until(lambda: strut_speed() > 2e-3, 30), "the reset did not move the robot home"
    sent = rec.now()
    goal = client.move(robot.home_pose + np.array([0.0, 0.0, 0.005, 0.0, 0.0, 0.0]))  # while it returns home
    second = client.move(robot.home_pose)
    assert second.outcome()[0] == "BUSY"  # the first goal waits for the struts: it is the running one
    name, message = goal.outcome(120)
    assert name == "SUCCEEDED", (name, message, logs(procs))
    stamps, pos, _ = rec.series(sent, np.inf)
    accel = second_differences(stamps, pos[:, :6])
    assert accel.max() <= robot.limits.strut_acceleration_max + ACCEL_TOL, accel.max()
    back_home(client, robot, procs)


def test_refusals_before_anything_moves_carry_their_codes(robot, suite):
    procs, client, rec = suite
    first = client.move(robot.home_pose + np.array([0.0, 0.0, 0.01, 0.0, 0.0, 0.0]))
    second = client.move(robot.home_pose)
    assert second.outcome()[0] == "BUSY"
    assert first.outcome(120)[0] == "SUCCEEDED", logs(procs)
    odd = client.move(robot.home_pose, frame="world")
    assert odd.outcome()[0] == "UNKNOWN_FRAME"
    back_home(client, robot, procs)

