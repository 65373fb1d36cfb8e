"""The stewart-vibration CLI (issue 2), run as a user would, in a subprocess."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np

from stewart_vibration import forward_kinematics, inverse_kinematics


def run_cli(*args):
    return subprocess.run(
        [sys.executable, "-m", "stewart_vibration", *args], capture_output=True, text=True, timeout=60
    )


def test_ik_json_matches_library(robot):
    pose = robot.home_pose + np.array([0.003, -0.002, 0.004, 0.05, -0.04, 0.1])
    out = run_cli("ik", *(str(float(v)) for v in pose), "--json")
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert np.allclose(data["lengths_m"], inverse_kinematics(robot, pose), atol=1e-15)
    assert len(data["universal_joint_deg"]) == 6


def test_ik_degrees_and_table(robot):
    out = run_cli("ik", "0", "0", "0.16", "0", "0", "10", "--deg")
    assert out.returncode == 0, out.stderr
    assert "leg_6" in out.stdout and "condition number" in out.stdout
    expected = inverse_kinematics(robot, [0, 0, 0.16, 0, 0, np.radians(10)])
    assert f"{expected[0]:.9f}" in out.stdout


def test_fk_round_trip(robot):
    pose = robot.home_pose + np.array([-0.004, 0.002, 0.001, -0.03, 0.02, 0.05])
    lengths = inverse_kinematics(robot, pose)
    out = run_cli("fk", *(str(float(v)) for v in lengths), "--json")
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert data["converged"] and data["assembly_ok"]
    assert np.allclose(list(data["pose"].values()), pose, atol=1e-10)
    assert data["iterations"] == int(forward_kinematics(robot, lengths).iterations)


def test_unreachable_pose_is_a_clear_error():
    out = run_cli("ik", "0", "0", "0.30", "0", "0", "0")
    assert out.returncode == 2
    assert "StrokeLimitError" in out.stderr and "leg 1" in out.stderr
    assert "Traceback" not in out.stderr


def test_offline_scenario_says_what_it_did():
    out = run_cli("offline-scenario", "--json")
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert "No ROS nodes were started" in data["what"]
    assert data["fk_pose_error"] < 1e-10
