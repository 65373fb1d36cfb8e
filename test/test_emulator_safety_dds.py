"""The robot no command can break, from the user's side: the hardware_emulator node as its own process over real
DDS, sent the commands that broke it, judged from its published 500 Hz joint states and true platform pose
against config/robot.yaml -- or shown to refuse the command (on /diagnostics) with the robot not moving.

- legal-per-strut trajectories that wrecked the platform (+45/-30 mm, +70/+70/-70/-70/0/0 mm): refused with the
  joint limit, the robot stays home;
- an e-stop just before the planned braking toward 0.1 mm short of stroke_max: no strut past the stroke;
- lifecycle deactivate during a move, and reset during an e-stop's braking: within the acceleration limit;
- an e-stop during a 49 Hz / 0.9 g vibration with vibration_ramp_s 0.005: within 1 g;
- a 1,000,000-point trajectory (176 MB): refused from its size, physics goes on at its rate;
- a stop (SIGINT) during a move: the emulator brakes the robot to rest before its physics ends;
- a physics divergence (a tissue that stiffens e-fold every micrometre): a latched fault, ERROR on
  /diagnostics and vibration/status, the robot held, /clock going on, nothing non-finite.
"""

from __future__ import annotations

import signal
import time
from pathlib import Path

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from lifecycle_msgs.msg import Transition
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from ros_client import node_under_test
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from test_emulation_stops import stroke_end_approach, vibration_window
from trajectory_msgs.msg import JointTrajectory

from stewart_vibration import inverse_kinematics
from stewart_vibration.install import default_config_dir
from stewart_vibration.kinematics import condition_number, joint_angles
from stewart_vibration.messages.joint_trajectory import encode_joint_trajectory
from stewart_vibration.messages.status_values import vibration_report_from_cdr
from stewart_vibration.motion.profiles import minimum_jerk, minimum_jerk_duration
from stewart_vibration.nodes.message_conversions import pose_from_msg
from stewart_vibration.robot import LEG_NAMES, VIB_NAMES
from stewart_vibration_interfaces.msg import LegTrajectoryStatus, Outcome, VibrationUnitsStatus

pytestmark = pytest.mark.integration
EMULATOR = "stewart_vibration.nodes.hardware_emulator_node"
STATUS_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
PERIOD = 0.002
# the published strut motion carries the servo tracking (and the units' tracking error), see
# test_emulator_safety_properties: allowances on top of the limits
STROKE_TOL = 1e-5  # m
ACCEL_TOL = 0.01  # m/s^2, second differences of the 500 Hz strut positions
ANGLE_TOL = 1e-4  # rad


class Recorder:
    """The emulator's streams as a user records them, as arrays."""

    def __init__(self, client):
        self.client = client
        self.states = client.subscribe("legs/joint_states", JointState, depth=10000)
        self.poses = client.subscribe("ground_truth/platform_pose", PoseStamped, depth=10000)
        self.clock = client.subscribe("/clock", Clock)
        self.diagnostics = client.subscribe("/diagnostics", DiagnosticArray)
        self.answers = client.subscribe("legs/trajectory_status", LegTrajectoryStatus)  # typed, per trajectory
        self.status: list = []
        client.node.create_subscription(VibrationUnitsStatus, "vibration/status", self.status.append, STATUS_QOS,
                                        raw=True)

    def now(self) -> float:
        c = self.clock[-1].clock if self.clock else None
        return 0.0 if c is None else c.sec + c.nanosec * 1e-9

    def wait_sim(self, until: float, timeout: float = 60.0) -> bool:
        return self.client.spin_until(lambda: self.now() >= until, timeout)

    def series(self, t0: float = -np.inf, t1: float = np.inf):
        """(stamps [n], positions [n, 12], velocities [n, 12]) of the joint states stamped in [t0, t1]."""
        stamps = np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in self.states])
        sel = np.flatnonzero((stamps >= t0) & (stamps <= t1))
        return (stamps[sel], np.array([self.states[i].position for i in sel]).reshape(-1, 12),
                np.array([self.states[i].velocity for i in sel]).reshape(-1, 12))

    def true_poses(self, t0: float = -np.inf, t1: float = np.inf):
        stamps = np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in self.poses])
        sel = np.flatnonzero((stamps >= t0) & (stamps <= t1))
        return np.array([pose_from_msg(self.poses[i].pose) for i in sel]).reshape(-1, 6)

    def rejections(self) -> list[str]:
        return [kv.value for a in self.diagnostics for s in a.status for kv in s.values if kv.key == "last_rejection"]


def second_differences(stamps, values):
    """Second differences / dt^2 of ``values`` [n, k] over consecutive 2 ms triples only (a lost sample breaks
    a triple, it does not make a step)."""
    gaps = np.diff(stamps)
    uniform = (np.abs(gaps[:-1] - PERIOD) < 1e-6) & (np.abs(gaps[1:] - PERIOD) < 1e-6)
    second = np.abs(values[2:] - 2 * values[1:-1] + values[:-2]) / PERIOD**2
    return second[uniform]


def assert_published_within_limits(robot, rec, t0, t1):
    lim = robot.limits
    stamps, pos, vel = rec.series(t0, t1)
    assert stamps.size and stamps.size > 0.8 * (min(t1, stamps[-1]) - t0) / PERIOD, "joint states were lost"
    assert (np.diff(stamps) > 0).all() and np.isfinite(pos).all() and np.isfinite(vel).all()
    struts = pos[:, :6]
    assert struts.min() >= lim.stroke_min - STROKE_TOL and struts.max() <= lim.stroke_max + STROKE_TOL, \
        (struts.min(), struts.max())
    accel = second_differences(stamps, struts)
    assert accel.size and accel.max() <= lim.strut_acceleration_max + ACCEL_TOL, accel.max()
    assert np.abs(vel[:, :6]).max() <= lim.strut_velocity_max * 1.001 + 5e-4
    poses = rec.true_poses(t0, t1)
    u, s = joint_angles(robot, poses)
    assert u.max() <= lim.universal_joint_max + ANGLE_TOL and s.max() <= lim.spherical_joint_max + ANGLE_TOL
    assert condition_number(robot, poses).max() <= lim.condition_number_max
    return stamps, pos


def strut_speed(rec) -> float:
    """The fastest strut's speed in the latest joint state (m/s; 0 before any)."""
    return float(np.abs(rec.states[-1].velocity[:6]).max()) if rec.states else 0.0


def wait_until_under_way(client, rec, robot, fraction: float = 0.8, timeout: float = 60.0) -> bool:
    """Until a strut moves at ``fraction`` of strut_velocity_max: the move's progress as the robot reports it,
    not a fixed time after sending (a busy machine may deliver the trajectory late)."""
    return client.spin_until(lambda: strut_speed(rec) > fraction * robot.limits.strut_velocity_max, timeout)


def started(client, rec, procs_log):
    assert client.spin_until(lambda: len(rec.states) > 20 and rec.status, 60), procs_log()
    assert client.wait_for_subscribers("legs/joint_trajectory")


def minjerk_bytes(robot, delta, speed=0.9, points=100):
    home = inverse_kinematics(robot, robot.home_pose)
    goal = home + np.asarray(delta)
    duration = minimum_jerk_duration(home, goal, speed * robot.limits.strut_velocity_max, 0.5)
    times = np.linspace(duration / points, duration, points)
    return encode_joint_trajectory(LEG_NAMES, 0.0, times, *minimum_jerk(home, goal, duration, times)), duration


def test_legal_per_strut_trajectories_that_wreck_the_platform_are_refused_and_nothing_moves(robot, ros_domain,
                                                                                           tmp_path):
    with node_under_test("emulator", EMULATOR, ros_domain, tmp_path) as (proc, client):
        rec = Recorder(client)
        started(client, rec, proc.log_text)
        legs = client.publisher("legs/joint_trajectory", JointTrajectory)
        t0 = rec.now()
        for delta in ([0.045, -0.03] * 3, [0.07, 0.07, -0.07, -0.07, 0.0, 0.0]):
            count = len(rec.rejections())
            data, duration = minjerk_bytes(robot, delta)
            legs.publish(data)
            assert client.spin_until(lambda c=count: len(rec.rejections()) > c, 20), proc.log_text()[-2000:]
            assert "universal_joint_max" in rec.rejections()[-1], rec.rejections()[-1]
            # the sender's typed answer: refused with the code, keyed by the trajectory's last point
            assert client.spin_until(lambda c=count: len(rec.answers) > c, 20)
            answer = rec.answers[-1]
            assert not answer.accepted and answer.outcome.code == Outcome.UNREACHABLE_POSE, answer
            home_lengths = inverse_kinematics(robot, robot.home_pose)
            assert np.allclose(answer.final_positions, home_lengths + np.asarray(delta), atol=1e-12)
        assert rec.wait_sim(t0 + 3.0)
        _, pos = assert_published_within_limits(robot, rec, t0, rec.now() - 0.01)
        home = inverse_kinematics(robot, robot.home_pose)
        assert np.abs(pos[:, :6] - home).max() < 1e-6  # nothing moved
        assert proc.alive()


def test_an_estop_before_the_braking_near_the_stroke_end_keeps_the_struts_inside_the_stroke(robot, ros_domain,
                                                                                           tmp_path):
    """Braking toward 0.1 mm short of stroke_max, the e-stop ~50 ms before the planned braking (it reached
    250.46-250.54 mm): the published strut lengths stay inside the stroke, the braking within its limit."""
    with node_under_test("emulator", EMULATOR, ros_domain, tmp_path) as (proc, client):
        rec = Recorder(client)
        started(client, rec, proc.log_text)
        home = inverse_kinematics(robot, robot.home_pose)
        t, pos, vel, acc, braking = stroke_end_approach(robot, home)
        begin = rec.now()
        client.publisher("legs/joint_trajectory", JointTrajectory).publish(
            encode_joint_trajectory(LEG_NAMES, 0.0, t, pos, vel, acc))
        assert rec.wait_sim(begin + braking - 0.05, 60)
        assert client.call(Trigger, "hardware_emulator/emergency_stop", Trigger.Request()).success
        stop_time = rec.now()
        assert rec.wait_sim(stop_time + 2.0)
        _, published = assert_published_within_limits(robot, rec, begin + 0.1, rec.now() - 0.01)
        assert published[:, :6].max() > robot.limits.stroke_max - 0.01  # it did go near the end
        assert published[:, :6].max() <= robot.limits.stroke_max - 1e-4 + STROKE_TOL


def test_deactivate_mid_move_and_reset_during_an_estop_braking_stay_within_the_acceleration_limit(robot, ros_domain,
                                                                                                 tmp_path):
    """Both used to step the strut velocity to zero (1.41-1.49 m/s^2, 15x the limit)."""
    with node_under_test("emulator", EMULATOR, ros_domain, tmp_path) as (proc, client):
        rec = Recorder(client)
        started(client, rec, proc.log_text)
        legs = client.publisher("legs/joint_trajectory", JointTrajectory)
        delta = [0.01, -0.01, 0.01, -0.01, 0.01, -0.01]
        # deactivate during a move at 90 % of the strut speed
        data, duration = minjerk_bytes(robot, delta)
        begin = rec.now()
        legs.publish(data)
        assert wait_until_under_way(client, rec, robot, 0.85), proc.log_text()  # near its 90 % peak
        assert client.transition("hardware_emulator", Transition.TRANSITION_DEACTIVATE)
        assert rec.wait_sim(rec.now() + 1.5)
        stamps, pos = assert_published_within_limits(robot, rec, begin, rec.now() - 0.01)
        moving = np.abs(np.diff(pos[:, :6], axis=0)).max(axis=1) / np.diff(stamps)
        assert moving.max() > 0.8 * robot.limits.strut_velocity_max and moving[-50:].max() < 1e-5  # moved, stopped
        assert client.transition("hardware_emulator", Transition.TRANSITION_ACTIVATE)
        # reset during the e-stop's braking: back home first, then the same move, e-stop, reset at once
        assert client.call(Trigger, "hardware_emulator/emergency_stop", Trigger.Request()).success
        assert client.call(Trigger, "hardware_emulator/reset", Trigger.Request()).success
        assert client.spin_until(lambda: at_home(robot, rec), 60)
        data, duration = minjerk_bytes(robot, delta)
        begin = rec.now()
        legs.publish(data)
        assert rec.wait_sim(begin + 0.5 * duration)
        assert client.call(Trigger, "hardware_emulator/emergency_stop", Trigger.Request()).success
        assert client.call(Trigger, "hardware_emulator/reset", Trigger.Request()).success
        assert client.spin_until(lambda: at_home(robot, rec), 120)
        assert_published_within_limits(robot, rec, begin, rec.now() - 0.01)
        assert proc.alive()


def test_a_vibration_estop_at_49_hz_and_09_g_with_a_5_ms_ramp_stays_within_1_g(robot, ros_domain, tmp_path):
    with node_under_test("emulator", EMULATOR, ros_domain, tmp_path,
                         ["--ros-args", "-p", "vibration_ramp_s:=0.005"]) as (proc, client):
        rec = Recorder(client)
        started(client, rec, proc.log_text)
        start = rec.now() + 0.5
        client.publisher("vibration/joint_trajectory", JointTrajectory).publish(
            encode_joint_trajectory(VIB_NAMES, start, *vibration_window(49.0, 0.9, 3.0)))
        assert client.spin_until(lambda: rec.status and report(rec.status[-1]).state == "running", 30)
        assert rec.wait_sim(start + 1.0)
        assert client.call(Trigger, "hardware_emulator/emergency_stop", Trigger.Request()).success
        assert client.spin_until(lambda: report(rec.status[-1]).state == "estopped", 10)
        at = report(rec.status[-1]).since
        assert rec.wait_sim(at + 2.5)
        stamps, pos, vel = rec.series(start, rec.now() - 0.01)
        units = pos[:, 6:]
        assert np.abs(units).max() > 0.9 * 9.3e-5  # it vibrated at 0.9 g
        accel = second_differences(stamps, units)  # at 500 Hz a 49 Hz sinusoid reads 3 % low
        assert accel.max() <= robot.vibration_unit.acceleration_max * 1.001, accel.max() / 9.80665
        assert np.abs(units[stamps > at + 2.1]).max() == 0.0
        assert_published_within_limits(robot, rec, start, rec.now() - 0.01)


def test_an_oversized_trajectory_is_refused_without_stalling_physics(robot, ros_domain, tmp_path):
    """1,000,000 legal points (176 MB): refused from the message's size, before it is decoded; the joint states
    go on at their rate, the robot does not move, the emulator's memory stays bounded."""
    with node_under_test("emulator", EMULATOR, ros_domain, tmp_path) as (proc, client):
        rec = Recorder(client)
        started(client, rec, proc.log_text)
        home = inverse_kinematics(robot, robot.home_pose)
        count = 1_000_000
        t = np.linspace(1e-3, 1000.0, count)
        ease = minimum_jerk(home, home + 0.001, 1000.0, t)
        data = encode_joint_trajectory(LEG_NAMES, 0.0, t, *ease)
        assert len(data) > 170e6
        rss_before = rss_bytes(proc.popen.pid)
        walls = []
        client.node.create_subscription(JointState, "legs/joint_states", lambda m: walls.append(time.monotonic()), 100)
        t0 = rec.now()
        client.publisher("legs/joint_trajectory", JointTrajectory).publish(data)
        assert client.spin_until(lambda: any("bytes" in r for r in rec.rejections()), 120), proc.log_text()[-2000:]
        assert client.spin_until(lambda: rec.answers, 20)
        answer = rec.answers[-1]  # refused from its size, unread: no points, no key
        assert not answer.accepted and answer.outcome.code == Outcome.LIMIT_EXCEEDED and answer.points == 0
        assert np.isnan(answer.final_positions).all()
        assert rec.wait_sim(rec.now() + 2.0)
        # physics never stalled (it did for 20 s); the reader is the process that just sent the 176 MB, whose own
        # publishing delays what it receives by about a second on this machine
        assert np.diff(walls).max() < 2.5
        _, pos = assert_published_within_limits(robot, rec, t0, rec.now() - 0.01)
        assert np.abs(pos[:, :6] - home).max() < 1e-6
        assert rss_bytes(proc.popen.pid) - rss_before < 1.0e9  # it grew by 4.3 GB
        assert proc.alive()


def test_stopping_the_emulator_mid_move_brakes_the_robot_to_rest_first(robot, ros_domain, tmp_path):
    """SIGINT during a move at 90 % of the strut speed: the joint states go on until the struts are at rest,
    braking within the acceleration limit, and then the process exits cleanly."""
    with node_under_test("emulator", EMULATOR, ros_domain, tmp_path) as (proc, client):
        rec = Recorder(client)
        started(client, rec, proc.log_text)
        data, duration = minjerk_bytes(robot, [0.01, -0.01, 0.01, -0.01, 0.01, -0.01])
        begin = rec.now()
        client.publisher("legs/joint_trajectory", JointTrajectory).publish(data)
        assert wait_until_under_way(client, rec, robot, 0.5), proc.log_text()
        proc.popen.send_signal(signal.SIGINT)
        assert client.spin_until(lambda: not proc.alive(), 20), proc.log_text()[-2000:]
        assert proc.popen.returncode == 0
        client.spin_for(0.5)  # the last states in flight
        stamps, pos = assert_published_within_limits(robot, rec, begin, np.inf)
        rates = np.abs(np.diff(pos[-6:, :6], axis=0)).max() / PERIOD
        assert rates < 1e-4, rates  # the last states published: at rest
        goal = inverse_kinematics(robot, robot.home_pose) + np.array([0.01, -0.01, 0.01, -0.01, 0.01, -0.01])
        # it stopped short: it did not run the move to its end (a busy machine delivers the signal late, so the
        # margin is not the braking distance of a signal on time)
        assert np.abs(pos[-1, :6] - goal).max() > 2e-4


def test_a_physics_divergence_latches_a_fault_reported_as_error_and_the_robot_is_held(robot, ros_domain, tmp_path):
    """A tissue stiffening e-fold every 1 um and a 2 mm distraction: the physics diverges (the physics thread died
    of it). The node latches the fault: ERROR with physics_fault on /diagnostics, vibration/status estopped with
    the fault, every command refused; the held state and /clock go on, finite, time never going back."""
    text = (default_config_dir() / "tissue.yaml").read_text().replace("length_m: 0.005", "length_m: 0.000001")
    (tmp_path / "stiff.yaml").write_text(text)
    # the tissue file check refuses such a tissue: a test wrapper of the node lifts that bound
    with node_under_test("emulator", "wall_tissue_emulator", ros_domain, tmp_path,
                         ["--ros-args", "-p", f"tissue_config:={tmp_path / 'stiff.yaml'}"],
                         pythonpath=Path(__file__).parent) as (proc, client):
        rec = Recorder(client)
        started(client, rec, proc.log_text)
        home = inverse_kinematics(robot, robot.home_pose)
        goal = inverse_kinematics(robot, robot.home_pose + np.array([0, 0, 0.002, 0, 0, 0]))
        times = np.linspace(0.05, 2.0, 40)
        client.publisher("legs/joint_trajectory", JointTrajectory).publish(
            encode_joint_trajectory(LEG_NAMES, 0.0, times, *minimum_jerk(home, goal, 2.0, times)))

        def fault_values():
            return [{kv.key: kv.value for kv in s.values} for a in rec.diagnostics for s in a.status
                    if s.level == DiagnosticStatus.ERROR and any(kv.key == "physics_fault" for kv in s.values)]

        assert client.spin_until(lambda: fault_values(), 60), proc.log_text()[-2000:]
        fault = fault_values()[-1]
        assert fault["physics_fault"] and float(fault["physics_fault_time_s"]) > 0
        assert client.spin_until(lambda: report(rec.status[-1]).fault == fault["physics_fault"], 10)
        assert report(rec.status[-1]).state == "estopped" and report(rec.status[-1]).level == "error"
        held_from = rec.now()
        assert rec.wait_sim(held_from + 1.0)  # /clock goes on
        stamps, pos, vel = rec.series(float(fault["physics_fault_time_s"]) + 0.01)
        assert stamps.size > 200 and (np.diff(stamps) > 0).all()
        assert np.isfinite(pos).all() and np.abs(vel).max() == 0.0 and np.ptp(pos, axis=0).max() == 0.0  # held
        all_stamps = rec.series()[0]
        assert (np.diff(all_stamps) > 0).all()  # never back in time
        count = len(rec.rejections())
        client.publisher("legs/joint_trajectory", JointTrajectory).publish(
            encode_joint_trajectory(LEG_NAMES, 0.0, times, *minimum_jerk(goal, home, 2.0, times)))
        assert client.spin_until(lambda: len(rec.rejections()) > count and "physics fault" in rec.rejections()[-1],
                                 10)
        assert proc.alive()


def at_home(robot, rec) -> bool:
    """The newest 25 joint states (50 ms) at the home lengths (1 um) and at rest (cheap: the predicate runs
    between the spins that keep up with the 500 Hz stream)."""
    if len(rec.states) < 25:
        return False
    newest = rec.states[-25:]
    pos = np.array([m.position[:6] for m in newest])
    vel = np.array([m.velocity[:6] for m in newest])
    home = inverse_kinematics(robot, robot.home_pose)
    return bool(np.abs(pos - home).max() < 1e-6 and np.abs(vel).max() < 1e-5)


def rss_bytes(pid: int) -> int:
    for line in open(f"/proc/{pid}/status"):
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024
    return 0


def report(data: bytes):
    """The VibrationReport of a raw vibration/status."""
    return vibration_report_from_cdr(data)

