"""hardware_emulator + kinematics nodes, each in its own process, on sim time over real DDS (issue 5)."""

from __future__ import annotations

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from ros_client import RosTestClient
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from stewart_vibration.emulation.emulator import VIB_NAMES
from stewart_vibration.nodes.common import duration_msg, pose_from_msg, pose_stamped
from stewart_vibration.paper import paper_pose
from stewart_vibration.processes import ros_environment, start_python_module

pytestmark = pytest.mark.integration
SIM = ["--ros-args", "-p", "use_sim_time:=true"]


@pytest.fixture
def suite(ros_domain, tmp_path):
    env = ros_environment(ros_domain)
    procs = [
        start_python_module("emulator", "stewart_vibration.nodes.hardware_emulator_node",
                            ["--ros-args", "-p", "real_time_factor:=0.0", "-p", "watchdog_s:=0.3"], env, tmp_path),
        start_python_module("kinematics", "stewart_vibration.nodes.kinematics_node", SIM, env, tmp_path),
    ]
    client = RosTestClient()
    try:
        yield procs, client
    finally:
        client.close()
        for proc in procs:
            proc.stop()


def logs(procs):
    return "\n".join(f"--- {p.name}\n{p.log_text()[-3000:]}" for p in procs)


def sim_now(clock):  # the client's latest /clock (it may lag the emulator)
    c = clock[-1].clock
    return c.sec + c.nanosec * 1e-9


def test_target_pose_reached_and_vibration_safety(robot, suite):
    procs, client = suite
    clock = client.subscribe("/clock", Clock)
    truth = client.subscribe("platform/pose", PoseStamped)
    states = client.subscribe("legs/joint_states", JointState)
    diagnostics = client.subscribe("/diagnostics", DiagnosticArray)
    estimates = client.subscribe("platform/pose_estimate", PoseStamped)
    assert client.spin_until(lambda: len(estimates) > 5, 30), logs(procs)

    # target pose -> ground truth within 10 um and 0.01 deg after settling
    target = paper_pose(robot)
    msg = pose_stamped(target, Time())
    client.publisher("platform/target_pose", PoseStamped).publish(msg)
    assert client.spin_until(lambda: len(clock) and sim_now(clock) > 1.0, 30)
    start = sim_now(clock)

    def settled():
        if not truth:
            return False
        err = pose_from_msg(truth[-1].pose) - target
        return np.abs(err[:3]).max() < 10e-6 and np.degrees(np.abs(err[3:]).max()) < 0.01

    assert client.spin_until(settled, 120), logs(procs)
    client.spin_until(lambda: sim_now(clock) > start + 9.0, 60)  # settle past the move (6.4 s)
    err = pose_from_msg(truth[-1].pose) - target
    assert np.abs(err[:3]).max() < 10e-6 and np.degrees(np.abs(err[3:]).max()) < 0.01

    # unsafe commands are rejected with a reason; the emulator survives
    bad = JointTrajectory(joint_names=[f"leg_{i}" for i in range(1, 7)])
    bad.points = [JointTrajectoryPoint(positions=[0.30] * 6, time_from_start=duration_msg(1.0))]
    client.publisher("legs/joint_trajectory", JointTrajectory).publish(bad)
    fast = JointTrajectory(joint_names=[f"leg_{i}" for i in range(1, 7)])
    fast.points = [JointTrajectoryPoint(positions=[0.20] * 6, time_from_start=duration_msg(0.1))]
    client.publisher("legs/joint_trajectory", JointTrajectory).publish(fast)

    def reasons():
        return " | ".join(s.message for a in diagnostics for s in a.status if "rejected" in s.message)

    assert client.spin_until(lambda: "stroke" in reasons() and "strut_velocity_max" in reasons(), 30), reasons()

    # a vibration window (stamp 0 = start on receipt), then silence: the watchdog (0.3 s here)
    # ramps it to zero within 100 ms, without a step
    t = np.arange(0.0, 2.0, 1e-3)
    w = 2 * np.pi * 35.0
    vib = JointTrajectory(joint_names=VIB_NAMES)
    amp = 30e-6 * np.sin(np.minimum(t / 0.2, 1.0) * np.pi / 2) ** 2  # smooth ramp-in from rest
    for ti, ai in zip(t, amp, strict=True):
        vib.points.append(JointTrajectoryPoint(positions=[float(ai * np.sin(w * ti))] * 6,
                                               velocities=[float(ai * w * np.cos(w * ti))] * 6,
                                               time_from_start=duration_msg(float(ti))))
    n0 = len(states)
    client.publisher("vibration/joint_trajectory", JointTrajectory).publish(vib)

    def stamps():
        return np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in states[n0:]])

    assert client.spin_until(lambda: len(states) > n0 and stamps()[-1] > stamps()[0] + 2.0, 60)
    seq = states[n0:]
    times = stamps()
    vibs = np.array([m.position[6:12] for m in seq])
    moving = np.flatnonzero(np.abs(vibs).max(axis=1) > 0)
    assert moving.size and np.abs(vibs).max() > 20e-6, (reasons(), logs(procs))
    received = times[moving[0]]  # first sample of the window
    assert times[moving[-1]] <= received + 0.3 + 0.1  # zero within 100 ms of the watchdog deadline
    assert (times[moving[-1]] - received) >= 0.25  # it did vibrate until the watchdog
    consecutive = np.diff(times) < 2.5e-3
    jumps = np.abs(np.diff(vibs, axis=0)).max(axis=1)[consecutive]
    assert jumps.max() < 30e-6 * w * 2e-3 * 1.5  # never faster than the sine itself

    # emergency stop and reset answer over the service
    res = client.call(Trigger, "hardware_emulator/emergency_stop", Trigger.Request())
    assert res.success and "held" in res.message
    res = client.call(Trigger, "hardware_emulator/reset", Trigger.Request())
    assert res.success and "home" in res.message
    assert all(p.alive() for p in procs), logs(procs)
