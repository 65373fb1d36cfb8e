"""The hardware_emulator node running the robot as built (plant_config), over real DDS: it says which plant
it runs, and its joint states are sensors: the struts' encoder counts, the units' noisy sensors, load cells
with their offsets."""

from __future__ import annotations

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from ros_client import RosTestClient
from sensor_msgs.msg import JointState

from stewart_vibration.emulation.plant import load_plant_option
from stewart_vibration.runtime.processes import ros_environment, start_python_module

pytestmark = pytest.mark.integration
EMULATOR = "stewart_vibration.nodes.hardware_emulator_node"


def test_the_emulator_node_runs_the_realistic_plant_and_reports_sensors(robot, ros_domain, tmp_path):
    plant = load_plant_option("realistic", robot, seed=3)
    assert plant is not None
    proc = start_python_module("emulator", EMULATOR, ["--ros-args", "-p", "plant_config:=realistic",
                                                      "-p", "plant_seed:=3"], ros_environment(ros_domain), tmp_path)
    client = RosTestClient()
    try:
        states = client.subscribe("legs/joint_states", JointState)
        diagnostics = client.subscribe("/diagnostics", DiagnosticArray)

        def said_plant():
            return [kv.value for a in diagnostics for s in a.status if s.name.endswith("hardware emulator")
                    for kv in s.values if kv.key == "plant"]

        assert client.spin_until(lambda: len(states) > 600 and said_plant(), 60), proc.log_text()[-3000:]
        assert said_plant()[-1] == "realistic (seed 3)"
        assert "plant realistic seed 3" in proc.log_text()
    finally:
        client.close()
        proc.stop()
    positions = np.array([m.position for m in states[100:]])
    efforts = np.array([m.effort for m in states[100:]])
    quantum = plant.sensors.encoder_quantization_m
    counts = positions[:, :6] / quantum
    assert np.allclose(counts, np.round(counts), atol=1e-6)  # whole encoder counts
    unit_std = positions[:, 6:].std(axis=0)
    assert np.all(np.abs(unit_std / plant.sensors.unit_sensor_noise_m - 1) < 0.2), unit_std
    # the load cells carry their offsets: at rest each leg's reading differs from the drawing's equal forces
    assert np.ptp(efforts[:, :6].mean(axis=0)) > 0.2
