"""hardware_emulator + kinematics nodes, each in its own process, on sim time over real DDS:
move goals (kinematics/move_to_pose) reach their target, unsafe strut commands are refused with a typed
answer (legs/trajectory_status), vibration windows splice or are refused, the watchdog ramps a command that
ends away from rest, nothing latches, and the e-stop holds until reset -- all observed as a user would (joint
states, vibration/status, legs/trajectory_status, /diagnostics)."""

from __future__ import annotations

import time

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from ros_client import RosTestClient
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from stewart_vibration.messages.joint_trajectory import encode_joint_trajectory
from stewart_vibration.messages.status_values import vibration_report_from_cdr
from stewart_vibration.nodes.message_conversions import duration_msg, pose_from_msg
from stewart_vibration.nodes.outcomes import outcome_name
from stewart_vibration.paper import paper_pose
from stewart_vibration.robot import VIB_NAMES
from stewart_vibration.runtime.processes import ros_environment, start_python_module
from stewart_vibration_interfaces.msg import LegTrajectoryStatus, VibrationUnitsStatus

pytestmark = pytest.mark.integration
SIM = ["--ros-args", "-p", "use_sim_time:=true"]
W, A = 2 * np.pi * 35.0, 30e-6
STATUS_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


@pytest.fixture
def suite(ros_domain, tmp_path):
    env = ros_environment(ros_domain)
    procs = [
        start_python_module("emulator", "stewart_vibration.nodes.hardware_emulator_node",
                            ["--ros-args", "-p", "real_time_factor:=1", "-p", "watchdog_s:=0.3"], env, tmp_path),
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


def vib_window(stamp: float, t0: float, t1: float, amp: float = A, at_rest_end: bool = True) -> bytes:
    """A vib_* window (raw) of amp e(t) sin(w t) on [t0, t1] s from ``stamp``: ramp-in from rest over 0.2 s
    and, with ``at_rest_end``, a ramp-out over the last 0.2 s (quintic smoothstep, written here)."""
    t = np.arange(round(t0 * 1000), round(t1 * 1000) + 1) / 1000.0

    def smooth(x):
        x = np.clip(x, 0, 1)
        return 10 * x**3 - 15 * x**4 + 6 * x**5, 30 * x**2 * (1 - x) ** 2 / 0.2

    e, de = smooth(t / 0.2)
    if at_rest_end:
        g, dg = smooth((t1 - t) / 0.2)
        e, de = e * g, de * g - e * dg
    pos = np.tile((amp * e * np.sin(W * t))[:, None], 6)
    vel = np.tile((amp * (de * np.sin(W * t) + e * W * np.cos(W * t)))[:, None], 6)
    return encode_joint_trajectory(VIB_NAMES, stamp, t, pos, vel)


def test_emulator_moves_vibrates_refuses_and_stops_safely(robot, suite):
    procs, client = suite
    clock = client.subscribe("/clock", Clock)
    truth = client.subscribe("ground_truth/platform_pose", PoseStamped)
    states = client.subscribe("legs/joint_states", JointState, depth=5000)
    diagnostics = client.subscribe("/diagnostics", DiagnosticArray)
    estimates = client.subscribe("platform/pose_estimate", PoseStamped)
    answers = client.subscribe("legs/trajectory_status", LegTrajectoryStatus)
    status = []
    client.node.create_subscription(VibrationUnitsStatus, "vibration/status", status.append, STATUS_QOS, raw=True)
    vib_pub = client.publisher("vibration/joint_trajectory", JointTrajectory)
    assert client.spin_until(lambda: len(estimates) > 5 and status, 30), logs(procs)
    assert report(status[-1]).state == "idle"

    # a move goal -> SUCCEEDED, the robot took its trajectory; ground truth within 10 um and 0.01 deg after settling
    target = paper_pose(robot)
    move = client.move(target)
    name, message = move.outcome(120)
    assert (name, move.status()) == ("SUCCEEDED", 4), (name, message, logs(procs))
    assert answers and all(a.accepted for a in answers), [(a.seq, a.outcome.message) for a in answers]

    def settled():
        if not truth:
            return False
        err = pose_from_msg(truth[-1].pose) - target
        return np.abs(err[:3]).max() < 10e-6 and np.degrees(np.abs(err[3:]).max()) < 0.01

    assert client.spin_until(settled, 120), logs(procs)

    # unsafe strut commands are refused, each with its typed answer (code and reason); the emulator survives
    answered = len(answers)
    legs = [f"leg_{i}" for i in range(1, 7)]
    bad = JointTrajectory(joint_names=legs)
    bad.points = [JointTrajectoryPoint(positions=[0.30] * 6, time_from_start=duration_msg(1.0))]
    client.publisher("legs/joint_trajectory", JointTrajectory).publish(bad)
    fast = JointTrajectory(joint_names=legs)
    fast.points = [JointTrajectoryPoint(positions=[0.20] * 6, time_from_start=duration_msg(0.1))]
    client.publisher("legs/joint_trajectory", JointTrajectory).publish(fast)

    assert client.spin_until(lambda: len(answers) >= answered + 2, 30), logs(procs)
    refused = answers[answered:]
    assert [(a.accepted, a.points) for a in refused] == [(False, 1), (False, 1)]
    assert refused[0].seq < refused[1].seq
    assert np.allclose(refused[0].final_positions, 0.30) and np.allclose(refused[1].final_positions, 0.20)
    kinds = [(outcome_name(a.outcome.code), a.outcome.message) for a in refused]
    assert kinds[0][0] == "UNREACHABLE_POSE" and "stroke" in kinds[0][1], kinds
    assert kinds[1][0] == "LIMIT_EXCEEDED" and "strut_velocity_max" in kinds[1][1], kinds
    assert all(np.isnan(a.end_time_s) for a in refused)

    def reasons():  # the emulator's rejections of vibration windows (no typed answer of their own)
        return " | ".join(s.message for a in diagnostics for s in a.status if "rejected" in s.message)

    # a window in the future, ending at rest: accepted, pending -> running -> idle ("commands ended")
    start = sim_now(clock) + 0.5
    vib_pub.publish(vib_window(start, 0.0, 1.0))
    assert client.spin_until(lambda: sim_now(clock) > start + 1.3, 30)
    seen = [report(m).state for m in status]
    assert {"pending", "running", "idle"} <= set(seen), seen
    assert report(status[-1]).state == "idle" and "commands ended" in report(status[-1]).reason
    played = vib_between(states, start, start + 1.0)
    assert 0.95 * A < np.abs(played).max() < 1.05 * A  # it vibrated at the commanded amplitude

    # a window that ends away from rest: the watchdog (0.3 s here) ramps it to zero within 100 ms, no step
    start = sim_now(clock) + 0.5
    vib_pub.publish(vib_window(start, 0.0, 0.6, at_rest_end=False))
    assert client.spin_until(lambda: sim_now(clock) > start + 1.2, 30)
    times, vib = vib_series(states, start - 0.1, start + 1.2)
    moving = np.flatnonzero(np.abs(vib).max(axis=1) > 0)
    assert np.abs(vib).max() > 0.9 * A
    assert times[moving[-1]] <= start + 0.6 + 0.1  # at rest within 100 ms past the end (the watchdog deadline)
    consecutive = np.diff(times) < 2.5e-3
    assert np.abs(np.diff(vib, axis=0)).max(axis=1)[consecutive].max() < A * W * 2e-3 * 1.5  # no step
    stopped = report(status[-1])
    assert stopped.state == "stopped" and "watchdog" in stopped.reason and stopped.level == "warn"

    # no latch: the next window from rest is accepted without reset
    start = sim_now(clock) + 0.5
    vib_pub.publish(vib_window(start, 0.0, 1.5))
    assert client.spin_until(lambda: sim_now(clock) > start + 0.5, 30)
    assert report(status[-1]).state == "running", [report(m).message for m in status[-3:]]

    # a discontinuous window (half the amplitude) is refused with the reason, the vibration goes on
    vib_pub.publish(vib_window(start, 0.7, 1.5, amp=A / 2))
    assert client.spin_until(lambda: report(status[-1]).event == "refused", 10)
    refusal = report(status[-1])
    assert refusal.event_outcome == "LIMIT_EXCEEDED" and "discontinuous splice" in refusal.event_reason
    assert abs(refusal.event_stamp - start) < 1e-6
    assert client.spin_until(lambda: "rejected vibration command: discontinuous splice" in reasons(), 5)

    # e-stop: the units ramp to zero within 100 ms, the status says estopped (ERROR), commands are refused,
    # the ERROR is never downgraded by a rejection, reset clears it (and is refused when nothing is latched)
    res = client.call(Trigger, "hardware_emulator/emergency_stop", Trigger.Request())
    assert res.success and "held" in res.message
    after_estop = len(diagnostics)
    assert client.spin_until(lambda: report(status[-1]).state == "estopped", 5)
    estop_at = report(status[-1]).since
    assert report(status[-1]).level == "error" and report(status[-1]).ramp_cause == "emergency_stop"
    assert client.spin_until(lambda: sim_now(clock) > estop_at + 0.3, 10)
    times, vib = vib_series(states, estop_at + 0.1, estop_at + 0.3)
    assert times.size > 50 and np.abs(vib).max() == 0.0
    vib_pub.publish(vib_window(sim_now(clock) + 0.5, 0.0, 1.0))
    assert client.spin_until(lambda: "emergency stop is active" in reasons(), 10)
    emulator_levels = [s.level for a in diagnostics[after_estop:] for s in a.status
                       if s.name.startswith("hardware_emulator")]
    assert emulator_levels and all(level == DiagnosticStatus.ERROR for level in emulator_levels)
    res = client.call(Trigger, "hardware_emulator/reset", Trigger.Request())
    assert res.success and "home" in res.message
    res = client.call(Trigger, "hardware_emulator/reset", Trigger.Request())
    assert not res.success and "no emergency stop is latched" in res.message
    assert all(p.alive() for p in procs), logs(procs)


def report(data: bytes):
    """The VibrationReport of a raw vibration/status."""
    return vibration_report_from_cdr(data)


def vib_series(states, t0, t1):
    """(stamps [n], vib_1..6 positions [n, 6]) of the joint states stamped in [t0, t1]."""
    stamps = np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in states])
    sel = (stamps >= t0) & (stamps <= t1)
    return stamps[sel], np.array([states[i].position[6:12] for i in np.flatnonzero(sel)]).reshape(-1, 6)


def vib_between(states, t0, t1):
    return vib_series(states, t0, t1)[1]


def test_above_real_time_physics_waits_for_late_estimates(ros_domain, tmp_path):
    """At real_time_factor 0 (as fast as possible) /clock keeps within max_consumer_lag_s of the newest
    platform/external_wrench_estimate this test publishes; it runs past an estimator silent for 2 s; at
    real_time_factor 1 it never waits (the hardware would not), unless ``lockstep`` is set (live)."""
    from geometry_msgs.msg import WrenchStamped
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters

    env = ros_environment(ros_domain)
    proc = start_python_module("emulator", "stewart_vibration.nodes.hardware_emulator_node",
                               ["--ros-args", "-p", "real_time_factor:=0.0", "-p", "max_consumer_lag_s:=0.1"],
                               env, tmp_path)
    client = RosTestClient()
    try:
        clock = client.subscribe("/clock", Clock)
        estimates = client.publisher("platform/external_wrench_estimate", WrenchStamped)
        assert client.wait_for_subscribers("platform/external_wrench_estimate", timeout=30), logs([proc])
        assert client.spin_until(lambda: len(clock) > 0, 30), logs([proc])

        def estimate_at(t: float) -> None:
            msg = WrenchStamped()
            msg.header.stamp = Time(sec=int(t), nanosec=int(round((t % 1) * 1e9)))
            estimates.publish(msg)

        def held_after(stamp: float, steady_s: float = 0.5) -> float:
            """The /clock once it has stood still for ``steady_s`` of wall time (at most 10 s) with the
            estimator at ``stamp``: a wait lasts at most 2 s of wall (then it is run past), so ``stamp``
            must be ahead of the clock by less than that, yet by more than a message's delay under load."""
            estimate_at(stamp)
            last, since, deadline = sim_now(clock), time.monotonic(), time.monotonic() + 10.0
            while time.monotonic() - since < steady_s and time.monotonic() < deadline:
                client.spin_for(0.05)
                if sim_now(clock) != last:
                    last, since = sim_now(clock), time.monotonic()
            return last

        # as fast as possible runs ~5x: 2 s of sim ahead is ~0.4 s of wall for the estimate to arrive first
        t0 = sim_now(clock) + 2.0
        held = held_after(t0)
        assert t0 - 0.1 < held <= t0 + 0.1 + 0.05, (t0, held, logs([proc]))
        moved = held_after(t0 + 0.5)
        assert t0 + 0.45 < moved <= t0 + 0.65, (t0, moved)
        client.spin_for(3.0)  # silent for longer than a wait may last: run past
        assert sim_now(clock) > moved + 1.0, (moved, sim_now(clock))

        request = SetParameters.Request(parameters=[Parameter(name="real_time_factor", value=ParameterValue(
            type=ParameterType.PARAMETER_DOUBLE, double_value=1.0))])
        assert client.call(SetParameters, "hardware_emulator/set_parameters", request).results[0].successful
        before = sim_now(clock)
        estimate_at(before - 5.0)  # far behind, but at 1x nobody is waited for
        client.spin_for(1.5)
        assert sim_now(clock) - before > 1.0, (before, sim_now(clock))

        request = SetParameters.Request(parameters=[Parameter(name="lockstep", value=ParameterValue(
            type=ParameterType.PARAMETER_BOOL, bool_value=True))])
        assert client.call(SetParameters, "hardware_emulator/set_parameters", request).results[0].successful
        assert client.wait_for_subscribers("platform/external_wrench_estimate", timeout=30), logs([proc])
        t1 = sim_now(clock) + 1.0
        held = held_after(t1)  # lockstep at 1x: held where real time would run on
        assert t1 - 0.1 < held <= t1 + 0.1 + 0.05, (t1, held)
        client.spin_for(0.5)
        assert sim_now(clock) == held, (held, sim_now(clock))  # still held: not the client's own stall
    finally:
        client.close()
        assert proc.stop() is not None


def test_a_command_sent_before_the_robot_listens_never_moves_it(robot, ros_domain, tmp_path):
    """The robot reads its command topics volatile: a leg trajectory latched (transient local, as a hostile or
    stale sender may offer it) before the emulator starts is never taken, the same trajectory sent once it
    listens is; the graph shows both of its command subscriptions volatile."""
    from stewart_vibration.kinematics.ik import inverse_kinematics

    client = RosTestClient()
    proc = None
    try:
        target = robot.home_pose + np.array([0.0, 0.0, 0.003, 0.0, 0.0, 0.0])
        move = JointTrajectory(joint_names=[f"leg_{i}" for i in range(1, 7)])
        move.points = [JointTrajectoryPoint(positions=[float(x) for x in inverse_kinematics(robot, target)],
                                            time_from_start=duration_msg(1.5))]
        latched = client.node.create_publisher(JointTrajectory, "legs/joint_trajectory", QoSProfile(
            depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        latched.publish(move)
        states = client.subscribe("legs/joint_states", JointState, depth=5000)
        answers = client.subscribe("legs/trajectory_status", LegTrajectoryStatus)
        proc = start_python_module("emulator", "stewart_vibration.nodes.hardware_emulator_node",
                                   ["--ros-args", "-p", "real_time_factor:=1"], ros_environment(ros_domain), tmp_path)
        assert client.spin_until(lambda: latched.get_subscription_count() >= 1 and len(states) > 10, 30), \
            logs([proc])
        def legs_of(msg):
            return np.array(msg.position[:6])

        start = legs_of(states[0])
        client.spin_for(3.0)  # twice the trajectory's duration, had it been taken
        assert not answers, [(a.accepted, a.outcome.message) for a in answers]
        assert np.abs(legs_of(states[-1]) - start).max() < 1e-6, legs_of(states[-1]) - start

        latched.publish(move)  # the same command, now that the robot listens: taken, and the legs move
        assert client.spin_until(lambda: answers and answers[-1].accepted, 20), logs([proc])
        assert client.spin_until(lambda: np.abs(legs_of(states[-1]) - start).max() > 1e-3, 20), logs([proc])

        def emulator_reads(topic: str) -> list:
            return [i.qos_profile.durability for i in client.node.get_subscriptions_info_by_topic(f"/{topic}")
                    if i.node_name == "hardware_emulator"]

        for topic in ("legs/joint_trajectory", "vibration/joint_trajectory"):
            assert client.spin_until(lambda: emulator_reads(topic), 10), topic  # noqa: B023 - used at once
            assert emulator_reads(topic) == [DurabilityPolicy.VOLATILE], (topic, emulator_reads(topic))
    finally:
        client.close()
        if proc is not None:
            proc.stop()
