"""`--robot other.yaml` reaches every node of the main job and changes what the suite does (every node used
config/robot.yaml whatever --robot said: a robot with a shorter stroke still passed).

A robot like the shipped one but with a 0.20 m stroke (instead of 0.25 m): the main scenario is refused
before anything starts (the paper pose needs 0.207 m), and the running suite, brought up with that robot,
refuses a plan the shipped robot accepts."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.srv import GetParameters

from stewart_vibration import check_pose, load_robot, pose_to_position_quaternion
from stewart_vibration.cli.main import main
from stewart_vibration.errors import StrokeLimitError
from stewart_vibration.nodes.suite_runner import RunOptions, SuiteRunner
from stewart_vibration.runtime.suite import SUITE_NODES
from stewart_vibration_interfaces.msg import Outcome
from stewart_vibration_interfaces.srv import PlanPath

CONFIG = Path(__file__).resolve().parents[1] / "stewart_vibration" / "config"
SHORT_STROKE_M = 0.200
GOAL_OFFSET = np.array([0.0, 0.0, 0.030, 0.0, 0.0, 0.0])  # legs 0.2023 m: inside 0.25, outside 0.20


@pytest.fixture
def short_robot(tmp_path) -> Path:
    tree = yaml.safe_load((CONFIG / "robot.yaml").read_text())
    tree["limits"]["stroke_max_m"] = SHORT_STROKE_M
    path = tmp_path / "short_robot.yaml"
    path.write_text(yaml.safe_dump(tree))
    return path


def test_a_shorter_stroke_refuses_the_main_scenario_before_anything_starts(short_robot, capsys, tmp_path):
    shipped = load_robot()
    assert main(["run", "--robot", str(short_robot), "--out", str(tmp_path / "run")]) == 2
    line = capsys.readouterr().err.strip()
    assert "step 0 move_to paper cannot be reached by the robot" in line and str(short_robot) in line, line
    assert "StrokeLimitError" in line and f"stroke {SHORT_STROKE_M:.6f} m" in line
    assert not (tmp_path / "run").exists()
    # the shipped robot takes the same pose (the refusal is the other robot's stroke, not the pose)
    from stewart_vibration.paper import paper_pose

    check_pose(shipped, paper_pose(shipped))


def pose_msg(pose) -> PoseStamped:
    position, q = pose_to_position_quaternion(pose)
    msg = PoseStamped()
    msg.header.frame_id = "base"
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = map(float, position)
    msg.pose.orientation.x, msg.pose.orientation.y, msg.pose.orientation.z, msg.pose.orientation.w = map(float, q)
    return msg


@pytest.mark.integration
def test_every_node_of_the_main_job_runs_the_given_robot(short_robot, tmp_path, ros_domain):
    shipped, short = load_robot(), load_robot(short_robot)
    goal = shipped.home_pose + GOAL_OFFSET
    check_pose(shipped, goal)  # the shipped robot can plan this move ...
    with pytest.raises(StrokeLimitError):
        check_pose(short, goal)  # ... the short one cannot
    runner = SuiteRunner(RunOptions(domain_id=ros_domain, out_dir=tmp_path / "run", robot_config=str(short_robot),
                                    progress=lambda *_: None))
    try:
        runner.start()
        runner.wait_ready()
        for node in (n.name for n in SUITE_NODES if n.robot_config):
            answer = runner.call(GetParameters, f"{node}/get_parameters", GetParameters.Request(names=["robot_config"]))
            assert answer.values[0].string_value == str(short_robot.resolve()), node
        request = PlanPath.Request(waypoints=[pose_msg(shipped.home_pose), pose_msg(goal)])
        answer = runner.call(PlanPath, "kinematics/plan_path", request)
        assert answer.outcome.code == Outcome.UNREACHABLE_POSE and not answer.path.poses  # refused: the stroke
        request.waypoints[1] = pose_msg(shipped.home_pose + GOAL_OFFSET / 3)  # within both strokes: still planned
        assert len(runner.call(PlanPath, "kinematics/plan_path", request).path.poses) > 2
    finally:
        runner.stop()
    assert not runner.record.failures, runner.record.failures
