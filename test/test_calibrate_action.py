"""The calibrate action over real DDS on the emulated robot as built (realistic plant, as fast as it runs):
`stewart-vibration calibrate` as a user runs it writes a robot file whose geometry, payload and load cell zeros are
judged against the plant file's truth (which only the test reads); plan-only moves nothing; bad goals and a cancel
write nothing."""

from __future__ import annotations

import subprocess
import time

import numpy as np
import pytest
from geometry_msgs.msg import PoseStamped
from ros_client import RosTestClient

from stewart_vibration import load_robot
from stewart_vibration.calibration.pose_plan import reachable_candidates
from stewart_vibration.emulation.plant import load_plant
from stewart_vibration.install import default_config_dir
from stewart_vibration.kinematics import forward_kinematics, inverse_kinematics
from stewart_vibration.runtime.processes import ros_environment, start_python_module
from stewart_vibration.safe_yaml import load_yaml
from stewart_vibration_interfaces.action import Calibrate
from stewart_vibration_interfaces.msg import CalibrationSample

pytestmark = [pytest.mark.integration, pytest.mark.slow]
SIM = ["--ros-args", "-p", "use_sim_time:=true"]
SEED = 3


@pytest.fixture
def suite(ros_domain, tmp_path):
    env = ros_environment(ros_domain)
    procs = [
        start_python_module("emulator", "stewart_vibration.nodes.hardware_emulator_node",
                            ["--ros-args", "-p", "plant_config:=realistic", "-p", f"plant_seed:={SEED}", "-p",
                             "real_time_factor:=0"], env, tmp_path),
        start_python_module("kinematics", "stewart_vibration.nodes.kinematics_node", SIM, env, tmp_path),
        start_python_module("estimator", "stewart_vibration.nodes.leg_force_estimator_node", SIM, env, tmp_path),
    ]
    client = RosTestClient()
    yield client, env, procs
    client.close()
    for proc in procs:
        proc.stop()


def logs(procs) -> str:
    return "\n".join(f"--- {p.name}\n{p.log_text()[-3000:]}" for p in procs)


def test_calibrate_writes_a_robot_file_that_matches_the_plant(suite, tmp_path):
    client, env, procs = suite
    samples = client.subscribe("kinematics/calibration_samples", CalibrationSample)
    estimates = client.subscribe("platform/pose_estimate", PoseStamped)
    # as a user runs it: on a suite that is up (a run prints "Nodes are running" once kinematics has states)
    assert client.spin_until(lambda: len(estimates) > 10, 120.0), logs(procs)
    output = tmp_path / "robot_calibrated.yaml"
    started = time.monotonic()
    done = subprocess.run(["stewart-vibration", "calibrate", "--namespace", "/", "--poses", "14", "--settle", "0.3",
                           "--window", "0.5", "--output", str(output)], env=env, capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, (done.stdout, done.stderr, logs(procs))
    assert "planned 14 poses: condition number" in done.stdout.splitlines()[0], done.stdout  # before any move
    assert "calibrate: SUCCEEDED" in done.stdout and str(output) in done.stdout
    client.spin_until(lambda: len(samples) >= 14, 10.0)
    assert [s.pose for s in samples] == list(range(1, 15)) and min(s.tracker_frames for s in samples) >= 15
    assert all(np.isfinite(s.load_cells_n).all() for s in samples)
    calibrated = load_robot(output)
    provenance = load_yaml(output, "robot config")["calibration"]
    assert provenance["poses_used"] == 14 and 0.3 < provenance["reduced_chi2"] < 3.0, provenance
    # the plant's truth: strut readings where the true robot stands at a pose -> FK of each model
    robot = load_robot()
    plant = load_plant(default_config_dir() / "plant_realistic.yaml", robot, seed=SEED)
    # its payload (7 % heavier than drawn) and its load cells' zeros, from the cells at rest
    print("payload", calibrated.payload.mass, "true", plant.robot.payload.mass, "offsets",
          calibrated.load_cell_offsets, "true", plant.sensors.load_cell_offsets_n)
    assert "payload" in done.stdout and provenance["payload"]["residual_rms_n"] < 0.05, provenance
    assert abs(calibrated.payload.mass / plant.robot.payload.mass - 1) < 0.035
    np.testing.assert_allclose(calibrated.payload.com[:2], plant.robot.payload.com[:2], atol=1e-3)
    np.testing.assert_allclose(calibrated.load_cell_offsets, plant.sensors.load_cell_offsets_n, atol=0.1)
    poses = reachable_candidates(robot, 30, 0.02, np.radians(15), np.random.default_rng(4))
    readings = inverse_kinematics(plant.robot, poses) - plant.strut_zero_offsets
    for model, bound in ((robot, None), (calibrated, 50e-6)):
        error = np.linalg.norm(forward_kinematics(model, readings, guess=poses).pose[:, :3] - poses[:, :3], axis=1)
        if bound is None:
            assert error.max() > 2e-4  # the drawing is a fraction of a millimetre off
        else:
            assert error.max() <= bound, error.max()
    print(f"calibrate: {time.monotonic() - started:.1f} s wall")


def test_plan_only_moves_nothing_and_bad_goals_and_a_cancel_write_nothing(suite, tmp_path):
    client, _, procs = suite
    estimates = client.subscribe("platform/pose_estimate", PoseStamped)
    assert client.spin_until(lambda: len(estimates) > 10, 120.0), logs(procs)
    assert client.action_server_ready(Calibrate, "kinematics/calibrate", 60.0), logs(procs)
    output = tmp_path / "never.yaml"
    precious = tmp_path / "precious.yaml"  # an existing file that is not a calibrated robot file
    precious.write_text("patient: data\n")
    planned = client.send_goal("kinematics/calibrate", Calibrate.Goal(poses=20, plan_only=True,
                                                                       output_path=str(output)), 30.0)
    name, message = planned.outcome(60.0)
    result = planned.result()
    assert name == "SUCCEEDED" and "nothing moved" in message and result.condition_number > 1.0
    assert result.predicted_std_max_m > 0 and result.path == "" and not output.exists()
    for goal, words in ((Calibrate.Goal(poses=5), "poses 5 outside"), (Calibrate.Goal(window_s=-1.0), "window_s"),
                        (Calibrate.Goal(tilt_deg=float("nan")), "tilt_deg must be finite"),
                        (Calibrate.Goal(output_path="/nonexistent/dir/robot.yaml"), "not a file"),
                        (Calibrate.Goal(output_path=str(precious)), "not overwritten"),
                        (Calibrate.Goal(output_path=str(tmp_path / "robot.txt")), "YAML file")):
        refused = client.send_goal("kinematics/calibrate", goal, 30.0)
        assert refused.outcome(30.0)[0] == "INVALID_ARGUMENT" and words in refused.outcome()[1], (
            refused.outcome(), logs(procs))
    running = client.send_goal("kinematics/calibrate", Calibrate.Goal(poses=14, output_path=str(output)), 30.0)
    assert client.spin_until(lambda: any(f.feedback.stage == "moving" for f in running.feedback), 60.0), logs(procs)
    running.handle.cancel_goal_async()
    assert running.outcome(60.0)[0] == "CANCELED", (running.outcome(), logs(procs))
    assert not output.exists() and not list(tmp_path.glob(".never.yaml*"))
    assert precious.read_text() == "patient: data\n"
