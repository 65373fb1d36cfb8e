"""leg-force estimator node in its own process over real DDS.

The test plays the emulator: a 35 Hz, 0.3 g platform vibration at the
paper's pose, commanded as vib_* windows (exact IK leg signals), measured as
joint states whose efforts are the Newton-Euler forces of the analytic
motion plus a known external wrench.
"""

from __future__ import annotations

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from rclpy.duration import Duration as RclpyDuration
from rclpy.serialization import serialize_message
from ros_client import node_under_test
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from stewart_vibration import decompose_vibration, inverse_kinematics, platform_vibration_motion, sample_leg_vibration
from stewart_vibration.dynamics.newton_euler import leg_forces
from stewart_vibration.paper import paper_pose

pytestmark = pytest.mark.integration

LEGS = [f"leg_{i}" for i in range(1, 7)]
VIB = [f"vib_{i}" for i in range(1, 7)]
T0 = 1000.0  # absolute start of the vibration (s, message stamps)
RAMP = 0.1
WRENCH = np.array([2.0, -1.5, 6.0, 0.12, -0.08, 0.03])  # on the platform, N and N m about its origin


@pytest.fixture
def estimator(ros_domain, tmp_path):
    with node_under_test("estimator", "stewart_vibration.nodes.leg_force_estimator_node", ros_domain, tmp_path) as pair:
        yield pair


def stamp(t: float) -> Time:
    ns = int(round(t * 1e9))
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def window(robot, plan, times):
    """vib_* window over relative times (s from T0), positions and velocities of the exact leg signals."""
    s = sample_leg_vibration(robot, plan, times, ramp_time=RAMP)
    msg = JointTrajectory()
    msg.header.stamp = stamp(T0)
    msg.joint_names = list(VIB)
    for t, p, v in zip(times, s.position.tolist(), s.velocity.tolist()):
        ns = int(round(t * 1e9))
        point = JointTrajectoryPoint(positions=p, velocities=v)
        point.time_from_start.sec, point.time_from_start.nanosec = ns // 1_000_000_000, ns % 1_000_000_000
        msg.points.append(point)
    return msg


def test_force_estimate_and_external_wrench(robot, estimator):
    proc, client = estimator
    forces = client.subscribe("legs/force_estimate", JointState)
    wrenches = client.subscribe("platform/external_wrench_estimate", WrenchStamped)
    diagnostics = client.subscribe("/diagnostics", DiagnosticArray)
    states = client.publisher("legs/joint_states", JointState, depth=1000)
    vib_pub = client.publisher("vibration/joint_trajectory", JointTrajectory)
    assert client.wait_for_subscribers("legs/joint_states"), proc.log_text()
    assert client.wait_for_subscribers("vibration/joint_trajectory"), proc.log_text()

    pose = paper_pose(robot)
    plan = decompose_vibration(robot, pose, acceleration_g=0.3, frequency=35.0)
    # two overlapping windows at 0.25 ms (the second replaces the first from its start on)
    dt = 2.5e-4
    vib_pub.publish(window(robot, plan, np.arange(0, 0.3 + dt / 2, dt)))
    vib_pub.publish(window(robot, plan, np.arange(0.2, 0.5 + dt / 2, dt)))
    assert vib_pub.wait_for_all_acked(RclpyDuration(seconds=10))  # delivered before the first state is sent

    # joint states at 500 Hz over [0.05, 0.45] s: legs at rest, vib_i exact, efforts = model + wrench
    t = np.arange(0.05, 0.45, 0.002)
    motion = platform_vibration_motion(plan, t, ramp_time=RAMP)
    twist = np.hstack([motion.velocity, motion.angular_velocity])
    accel = np.hstack([motion.acceleration, motion.angular_acceleration])
    truth = leg_forces(robot, motion.pose, twist, accel)
    measured = leg_forces(robot, motion.pose, twist, accel, external_wrench=WRENCH)
    vib = sample_leg_vibration(robot, plan, t, ramp_time=RAMP)
    struts = inverse_kinematics(robot, pose)
    for i, ti in enumerate(t):
        msg = JointState()
        msg.header.stamp = stamp(T0 + ti)
        msg.name = LEGS + VIB
        msg.position = struts.tolist() + vib.position[i].tolist()
        msg.velocity = [0.0] * 6 + vib.velocity[i].tolist()
        msg.effort = measured[i].tolist() * 2
        states.publish(msg)
        if i % 20 == 19:
            client.spin_for(0.02)
    assert client.spin_until(lambda: len(forces) >= len(t) and len(wrenches) >= len(t), 20), proc.log_text()

    by_stamp = {(m.header.stamp.sec, m.header.stamp.nanosec): np.array(m.effort) for m in forces}
    estimate = np.array([by_stamp[(s.sec, s.nanosec)] for s in map(stamp, T0 + t)])
    amplitude = (truth.max(axis=0) - truth.min(axis=0)) / 2  # force amplitude per leg (N)
    error = np.abs(estimate - truth).max(axis=0)
    print("force amplitude N", amplitude.round(4), "max error N", error, "relative", (error / amplitude).max())
    assert (error <= 2e-3 * amplitude).all()  # cubic Hermite of 0.25 ms samples: ~3e-4 expected

    got = np.array([[w.wrench.force.x, w.wrench.force.y, w.wrench.force.z,
                     w.wrench.torque.x, w.wrench.torque.y, w.wrench.torque.z] for w in wrenches[-len(t):]])
    assert all(w.header.frame_id == "base" for w in wrenches)
    np.testing.assert_allclose(got, np.tile(WRENCH, (len(t), 1)), atol=0.02)
    print("wrench error max", np.abs(got - WRENCH).max(axis=0))

    def values():
        out = {}
        for a in diagnostics:
            for s in a.status:
                out.update({kv.key: kv.value for kv in s.values})
        return out

    assert client.spin_until(lambda: "rms_error_n" in values(), 5)
    # RMS of measured - model = the wrench's leg forces (the model knows no external wrench)
    extra = measured - truth
    assert abs(float(values()["rms_error_n"]) - np.sqrt((extra**2).mean())) < 0.05 * np.sqrt((extra**2).mean())

    # malformed inputs: ignored with a reason, the node keeps running
    count = len(forces)
    bad_names = JointState(name=LEGS[:5] + VIB, position=[0.2] * 11, velocity=[0.0] * 11)
    nan = JointState(name=LEGS + VIB, position=struts.tolist() + [float("nan")] * 6, velocity=[0.0] * 12)
    states.publish(bad_names)
    states.publish(nan)
    states.publish(serialize_message(nan)[:40])  # raw CDR cut short: dropped alone, with its reason
    backwards = window(robot, plan, np.array([0.0, 0.1, 0.05]))
    vib_pub.publish(backwards)
    wrong = window(robot, plan, np.array([0.0, 0.1]))
    wrong.joint_names = LEGS
    vib_pub.publish(wrong)

    def malformed():  # counted per input on /diagnostics, each reason in the log (the first of each)
        v = values()
        return int(v.get("malformed legs/joint_states", 0)), int(v.get("malformed vibration/joint_trajectory", 0))

    assert client.spin_until(lambda: malformed()[0] >= 3 and malformed()[1] >= 2, 10), values()
    log = proc.log_text()
    assert all(k in log for k in ("needs ['leg_1'", "without finite positions", "truncated", "increasing",
                                  "joint names")), log
    client.spin_for(0.2)
    assert len(forces) == count
    assert proc.alive()
