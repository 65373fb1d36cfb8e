"""The stewart-vibration CLI, run as a user would, in a subprocess.

Every number is checked against the independent references (hinges rebuilt
from robot.yaml, textbook rotations, per-leg loops), not the library.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from reference import config_hinges, reference_lengths, reference_rotation
from vibration_reference import jacobian_ref

pytestmark = pytest.mark.integration  # each test starts a Python process

PAPER_OFFSET = [0.002, 0.002, 0.002, np.pi / 15, np.pi / 12, np.pi / 18]  # the paper's X = Y = Z = 2 mm and angles


def run_cli(*args):
    return subprocess.run(
        [sys.executable, "-m", "stewart_vibration", *args], capture_output=True, text=True, timeout=120
    )


def reference_ik(robot, pose):
    """Lengths, universal and spherical joint angles (deg) and the homogeneous condition number."""
    base, platform = config_hinges(robot.source)
    rot = reference_rotation(*pose[3:])
    jac, lengths, n = jacobian_ref(robot, pose)
    np.testing.assert_allclose(lengths, reference_lengths(base, platform, pose), rtol=0, atol=1e-15)
    universal = np.degrees(np.arccos(n[:, 2]))
    spherical = np.degrees(np.arccos(n @ rot[:, 2]))
    scale = np.linalg.norm(platform[:, :2], axis=1).mean()  # characteristic length: mean platform radius
    sv = np.linalg.svd(jac * np.r_[1.0, 1.0, 1.0, [1.0 / scale] * 3], compute_uv=False)
    return lengths, universal, spherical, sv[0] / sv[-1]


def test_ik_json_matches_reference(robot):
    pose = robot.home_pose + np.array([0.003, -0.002, 0.004, 0.05, -0.04, 0.1])
    out = run_cli("ik", *(str(float(v)) for v in pose), "--json")
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    lengths, universal, spherical, cond = reference_ik(robot, pose)
    np.testing.assert_allclose(data["lengths_m"], lengths, rtol=0, atol=1e-14)
    np.testing.assert_allclose(data["universal_joint_deg"], universal, rtol=0, atol=1e-9)
    np.testing.assert_allclose(data["spherical_joint_deg"], spherical, rtol=0, atol=1e-9)
    assert data["condition_number"] == pytest.approx(cond, rel=1e-10)
    assert list(data["pose"].values()) == list(pose)


def test_ik_degrees_and_table(robot):
    out = run_cli("ik", "0", "0", "0.16", "0", "0", "10", "--deg")
    assert out.returncode == 0, out.stderr
    lengths, universal, spherical, cond = reference_ik(robot, np.array([0, 0, 0.16, 0, 0, np.radians(10)]))
    rows = {line.split()[0]: line.split() for line in out.stdout.splitlines() if line.startswith("leg_")}
    assert sorted(rows) == [f"leg_{i}" for i in range(1, 7)]
    for i in range(6):
        got = [float(v) for v in rows[f"leg_{i + 1}"][1:4]]
        np.testing.assert_allclose(got, [lengths[i], universal[i], spherical[i]], rtol=1e-6, atol=1e-9)
    assert f"condition number (dimensionally homogeneous): {cond:.4f}" in out.stdout


def test_fk_round_trip(robot):
    base, platform = config_hinges(robot.source)
    pose = robot.home_pose + np.array([-0.004, 0.002, 0.001, -0.03, 0.02, 0.05])
    lengths = reference_lengths(base, platform, pose)
    out = run_cli("fk", *(str(float(v)) for v in lengths), "--json")
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert data["converged"] and data["assembly_ok"]
    got = np.array(list(data["pose"].values()))
    np.testing.assert_allclose(got, pose, rtol=0, atol=1e-10)
    # the reported residual is the leg-length mismatch of the reported pose
    assert data["residual_m"] <= 1e-12
    assert np.abs(reference_lengths(base, platform, got) - lengths).max() <= 1e-12
    assert 1 <= data["iterations"] <= 10  # cold start from home, Newton
    # warm start 1 um / 1e-5 rad away: 1-2 Newton iterations
    guess = pose + np.array([1e-6, -1e-6, 1e-6, 1e-5, -1e-5, 1e-5])
    warm = run_cli("fk", *(str(float(v)) for v in lengths), "--guess", *(str(float(v)) for v in guess), "--json")
    assert warm.returncode == 0, warm.stderr
    data = json.loads(warm.stdout)
    assert 1 <= data["iterations"] <= 2
    np.testing.assert_allclose(list(data["pose"].values()), pose, rtol=0, atol=1e-10)


def test_fk_other_assembly_mode_exits_3(robot):
    base, platform = config_hinges(robot.source)
    pose = robot.home_pose
    mirrored = pose * np.array([1, 1, -1, 1, 1, 1])
    out = run_cli("fk", *(str(float(v)) for v in reference_lengths(base, platform, pose)),
                  "--guess", *(str(float(v)) for v in mirrored), "--json")
    assert out.returncode == 3, out.stdout + out.stderr
    data = json.loads(out.stdout)
    assert data["converged"] and not data["assembly_ok"]


def test_unreachable_pose_is_a_clear_error(robot):
    base, platform = config_hinges(robot.source)
    too_long = reference_lengths(base, platform, np.array([0, 0, 0.30, 0, 0, 0]))
    assert (too_long > robot.limits.stroke_max).all()  # every leg is past the stroke: leg 1 is named first
    out = run_cli("ik", "0", "0", "0.30", "0", "0", "0")
    assert out.returncode == 2
    assert "StrokeLimitError" in out.stderr and "leg 1" in out.stderr
    assert "Traceback" not in out.stderr


def test_offline_scenario_says_what_it_did(robot):
    out = run_cli("offline-scenario", "--json")
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert "No ROS nodes were started" in data["what"]
    paper = robot.home_pose + PAPER_OFFSET
    base, platform = config_hinges(robot.source)
    np.testing.assert_allclose(data["paper_pose"], paper, rtol=0, atol=1e-15)
    np.testing.assert_allclose(data["lengths_home_m"], reference_lengths(base, platform, robot.home_pose),
                               rtol=0, atol=1e-14)
    np.testing.assert_allclose(data["lengths_paper_m"], reference_lengths(base, platform, paper), rtol=0, atol=1e-14)
    np.testing.assert_allclose(data["fk_pose"], paper, rtol=0, atol=1e-10)
    assert data["fk_pose_error"] == pytest.approx(np.abs(np.array(data["fk_pose"]) - paper).max(), abs=1e-15)
    assert data["condition_number"] == pytest.approx(reference_ik(robot, paper)[3], rel=1e-10)


def test_the_command_line_loads_mujoco_only_for_the_commands_that_simulate():
    """Building the parser imports every subcommand's module: none may import MuJoCo at import time, or the
    report of an hour's run (which never simulates) carries its ~50 MB of peak memory (benchmarks/long_runs.py)."""
    probe = ("import sys\nfrom stewart_vibration.cli.main import build_parser\nbuild_parser()\n"
             "print(sorted(m for m in sys.modules if m.split('.')[0] in ('mujoco', 'rclpy', 'matplotlib', 'scipy')))")
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.strip() == "[]", result.stdout
