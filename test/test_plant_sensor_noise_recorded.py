"""The sensors' noise in a recorded run matches the plant file: the emulator on the realistic plant at rest,
the recorder writing its MCAP, and each sensor read back against its ground_truth/ twin at the same stamp:
encoders within half a count of the true strut length minus its zero offset, the unit sensors' and load
cells' error RMS within 10 % of their figures with no bias beyond their offsets, the IMU's noise RMS within
10 % of its density over the Nyquist band around its bias, the tracker's position noise within 10 %."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.emulation.plant import load_plant_option
from stewart_vibration.emulation.platform_sensors import band_rms
from stewart_vibration.mcap_log import RunReader
from stewart_vibration.runtime.processes import ros_environment, start_python_module, wait_for

pytestmark = pytest.mark.integration
EMULATOR = "stewart_vibration.nodes.hardware_emulator_node"
RECORDER = "stewart_vibration.nodes.mcap_recorder_node"
SEED = 5
STATES = 2500  # 5 s at 500 Hz


def _by_stamp(run: RunReader, topic: str) -> dict:
    return {raw.publish_time: msg for raw, msg in run.decoded([topic])}


def test_recorded_sensor_noise_matches_the_plant_file(robot, ros_domain, tmp_path):
    plant = load_plant_option("realistic", robot, seed=SEED)
    assert plant is not None
    s = plant.sensors
    env = ros_environment(ros_domain)
    out = tmp_path / "rec"
    recorder = start_python_module("recorder", RECORDER, ["--ros-args", "-p", f"output_dir:={out}"], env, tmp_path)
    emulator = start_python_module("emulator", EMULATOR, ["--ros-args", "-p", "plant_config:=realistic",
                                                          "-p", f"plant_seed:={SEED}"], env, tmp_path)
    try:
        def recorded() -> int:
            files = sorted(out.glob("*.mcap"))
            try:
                return sum(1 for _ in RunReader(files[0]).messages(["/ground_truth/joint_states"])) if files else 0
            except Exception:  # noqa: BLE001 - a file being written can be momentarily unreadable
                return 0

        assert wait_for(lambda: recorded() > STATES + 500, 120, interval_s=1.0), recorder.log_text()[-2000:]
    finally:
        emulator.stop()
        recorder.stop()
    run = RunReader(sorted(out.glob("*.mcap"))[0])
    sensed, truth = _by_stamp(run, "/legs/joint_states"), _by_stamp(run, "/ground_truth/joint_states")
    stamps = sorted(set(sensed) & set(truth))[500:]  # past the start
    assert len(stamps) >= STATES
    position = np.array([sensed[t].position for t in stamps])
    true_position = np.array([truth[t].position for t in stamps])
    effort = np.array([sensed[t].effort for t in stamps])
    true_effort = np.array([truth[t].effort for t in stamps])
    # encoders: whole counts of the true length minus the zero offset
    encoder_error = position[:, :6] - (true_position[:, :6] - plant.strut_zero_offsets)
    assert np.all(np.abs(encoder_error) <= s.encoder_quantization_m / 2 + 1e-12)
    # unit sensors and load cells: white noise of their RMS, no bias but the load cells' offsets
    unit_error = position[:, 6:] - true_position[:, 6:]
    cell_error = effort[:, :6] - true_effort[:, :6] - s.load_cell_offsets_n
    n = len(stamps)
    for error, rms in ((unit_error, s.unit_sensor_noise_m), (cell_error, s.load_cell_noise_n)):
        assert np.all(np.abs(error.std(axis=0) / rms - 1) < 0.1), error.std(axis=0) / rms
        assert np.all(np.abs(error.mean(axis=0)) < 5 * rms / np.sqrt(n)), error.mean(axis=0) / rms
    # IMU: at rest the truth is gravity, constant; the noise about the bias has the band RMS
    imu = [msg for _raw, msg in run.decoded(["/platform/imu"])][500:]
    accel = np.array([[m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z] for m in imu])
    gyro = np.array([[m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z] for m in imu])
    rate = 500.0
    assert np.all(np.abs(accel.std(axis=0) / band_rms(s.accel_noise_density, rate) - 1) < 0.1)
    assert np.all(np.abs(gyro.std(axis=0) / band_rms(s.gyro_noise_density, rate) - 1) < 0.1)
    assert np.allclose(gyro.mean(axis=0), s.gyro_bias_rad_s, atol=5 * band_rms(s.gyro_noise_density, rate)
                       / np.sqrt(len(imu)))
    # tracker: its frames against the true pose at their capture stamps
    poses = _by_stamp(run, "/ground_truth/platform_pose")
    frames = [(raw.publish_time, msg) for raw, msg in run.decoded(["/platform/tracker_pose"])]
    paired = [(msg, poses[t]) for t, msg in frames if t in poses][30:]
    assert len(paired) >= 200
    error = np.array([[m.pose.position.x - p.pose.position.x, m.pose.position.y - p.pose.position.y,
                       m.pose.position.z - p.pose.position.z] for m, p in paired])
    assert np.all(np.abs(error.std(axis=0) / s.tracker_position_noise_m - 1) < 0.15)  # ~250 frames: 4.5 % RMS
