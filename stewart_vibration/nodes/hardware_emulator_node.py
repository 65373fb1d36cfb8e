"""hardware_emulator node: the robot in MuJoCo, owning /clock (sim time).

Topics (relative): sub legs/joint_trajectory (leg_*, absolute strut lengths),
vibration/joint_trajectory (vib_*, header stamp = common start time); pub
legs/joint_states (leg_*, vib_*: position m, velocity m/s, effort = axial
force N), platform/pose (ground truth, PoseStamped in `base`),
robot_markers (visualization_msgs/MarkerArray), /clock, /diagnostics.
Services: hardware_emulator/reset, hardware_emulator/emergency_stop (Trigger).

Physics runs in its own thread, paced by ``real_time_factor`` (0 = as fast as
possible); commands arrive on the executor thread and are handed over under a lock.
"""

from __future__ import annotations

import threading
import time

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, PoseStamped
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import Marker, MarkerArray

from ..emulation.emulator import HardwareEmulator
from ..errors import StewartError
from ..mjcf import load_simulation_settings
from ..robot import load_robot
from ..rotations import rotation_from_rpy
from .common import (
    ERROR,
    OK,
    STREAM_DEPTH,
    Diagnostics,
    duration_seconds,
    float_param,
    int_param,
    pose_stamped,
    reject,
    run_node,
    stamp_seconds,
    text_param,
)


def sim_time_msg(seconds: float) -> Time:
    sec, nanosec = divmod(int(round(seconds * 1e9)), 1_000_000_000)  # 4.9999999999 -> 5 s, not 4 s
    return Time(sec=sec, nanosec=nanosec)


class HardwareEmulatorNode(Node):
    """Thin adapter over stewart_vibration.emulation.HardwareEmulator."""

    def __init__(self):
        super().__init__("hardware_emulator")
        self.declare_parameter("robot_config", "", text_param("robot YAML ('' = config/robot.yaml)", True))
        self.declare_parameter("simulation_config", "", text_param("simulation YAML ('' = config/simulation.yaml)",
                                                                   True))
        self.declare_parameter("physics_rate_hz", 2000.0, float_param("physics steps per simulated second", 200, 20000))
        self.declare_parameter("state_rate_hz", 500.0,
                               float_param("joint state / pose / clock rate (sim time)", 10, 5000))
        self.declare_parameter("clock_rate_hz", 100.0, float_param(
            "/clock rate (sim time); every sim-time node wakes for each tick, so keep it modest", 10, 5000))
        self.declare_parameter("real_time_factor", 1.0,
                               float_param("sim seconds per wall second; 0 = as fast as possible", 0.0, 100.0))
        self.declare_parameter("watchdog_s", 0.5, float_param("vibration ramps out after this long without commands",
                                                              0.02, 10.0))
        self.declare_parameter("vibration_ramp_s", 0.05, float_param("vibration ramp-out time, s", 0.005, 0.1))
        self.declare_parameter("drive_gain_interval", 10, int_param(
            "physics steps between recomputing the strut drive's force-to-acceleration map", 1, 1000))
        self.declare_parameter("marker_rate_hz", 10.0, float_param("MarkerArray rate (sim time)", 0.0, 100.0))
        param = self.get_parameter
        robot = load_robot(param("robot_config").value or None)
        settings = load_simulation_settings(param("simulation_config").value or None,
                                            timestep=1.0 / param("physics_rate_hz").value)
        self.emulator = HardwareEmulator(robot, settings, param("watchdog_s").value, param("vibration_ramp_s").value,
                                         param("drive_gain_interval").value)
        self.lock = threading.Lock()
        self.diagnostics = Diagnostics(self, "hardware emulator")
        self.state_pub = self.create_publisher(JointState, "legs/joint_states", STREAM_DEPTH)
        self.pose_pub = self.create_publisher(PoseStamped, "platform/pose", STREAM_DEPTH)
        self.clock_pub = self.create_publisher(Clock, "/clock", 10)
        self.marker_pub = self.create_publisher(MarkerArray, "robot_markers", 5)
        self.create_subscription(JointTrajectory, "legs/joint_trajectory", self.on_leg_trajectory, 10)
        self.create_subscription(JointTrajectory, "vibration/joint_trajectory", self.on_vibration, 50)
        self.create_service(Trigger, "hardware_emulator/reset", self.on_reset)
        self.create_service(Trigger, "hardware_emulator/emergency_stop", self.on_emergency_stop)
        self.running = True
        self.achieved_rtf = 0.0
        self.thread = threading.Thread(target=self.physics_loop, name="physics", daemon=True)
        self.thread.start()
        self.diagnostics.set(OK, "running", physics_rate_hz=param("physics_rate_hz").value)
        self.get_logger().info(f"hardware emulator running (MuJoCo dt {self.emulator.dt} s, robot {robot.source})")

    # -- commands (executor thread) ------------------------------------------------
    @staticmethod
    def _points(msg: JointTrajectory):
        times = [duration_seconds(p.time_from_start) for p in msg.points]
        return (times, [p.positions for p in msg.points], [p.velocities for p in msg.points],
                [p.accelerations for p in msg.points])

    def on_leg_trajectory(self, msg: JointTrajectory) -> None:
        times, pos, vel, acc = self._points(msg)
        try:
            with self.lock:
                self.emulator.command_struts(msg.joint_names, stamp_seconds(msg.header.stamp), times, pos, vel, acc)
        except StewartError as exc:
            reject(self, self.diagnostics, "leg trajectory", str(exc))
            return
        self.diagnostics.set(OK, "following leg trajectory", last_leg_trajectory_points=len(times))

    def on_vibration(self, msg: JointTrajectory) -> None:
        times, pos, vel, _ = self._points(msg)
        try:
            with self.lock:
                self.emulator.command_vibration(msg.joint_names, stamp_seconds(msg.header.stamp), times, pos, vel)
        except StewartError as exc:
            reject(self, self.diagnostics, "vibration command", str(exc))

    def on_emergency_stop(self, request, response):
        with self.lock:
            self.emulator.emergency_stop()
        self.get_logger().warning("emergency stop: vibration ramping to zero, pose held")
        self.diagnostics.set(ERROR, "emergency stop (call hardware_emulator/reset to clear)")
        response.success, response.message = True, "vibration ramping to zero, pose held; reset to clear"
        return response

    def on_reset(self, request, response):
        with self.lock:
            duration = self.emulator.reset()
        self.diagnostics.set(OK, "reset: returning home")
        response.success = True
        response.message = f"returning home over {duration:.2f} s (sim time); e-stop cleared"
        return response

    # -- physics (own thread) --------------------------------------------------------
    def physics_loop(self) -> None:
        period = 1.0 / self.get_parameter("state_rate_hz").value
        rtf = self.get_parameter("real_time_factor").value
        marker_every = self._marker_every(period)
        clock_every = max(int(round(1.0 / (self.get_parameter("clock_rate_hz").value * period))), 1)
        wall0, sim0, cycle = time.monotonic(), self.emulator.time, 0
        self.publish_state()
        while self.running:
            with self.lock:
                self.emulator.advance(period)
                state = self.emulator.joint_state()
                pose = self.emulator.platform_pose()
                now = self.emulator.time
            cycle += 1
            if not self.running:
                break  # shutting down: the context may already be gone
            self.publish_state(state, pose, now, clock=cycle % clock_every == 0)
            if marker_every and cycle % marker_every == 0:
                self.publish_markers(pose, now)
            wall = time.monotonic() - wall0
            self.achieved_rtf = (now - sim0) / wall if wall > 0 else 0.0
            if rtf > 0:
                ahead = (now - sim0) / rtf - wall
                if ahead > 0:
                    time.sleep(ahead)
            if cycle % 500 == 0:
                self.diagnostics.values.update(sim_time_s=f"{now:.3f}", achieved_rtf=f"{self.achieved_rtf:.2f}",
                                               constraint_violation_m=f"{self.emulator.sim.constraint_violation():.3g}")

    def _marker_every(self, period: float) -> int:
        rate = self.get_parameter("marker_rate_hz").value
        return max(int(round(1.0 / (rate * period))), 1) if rate > 0 else 0

    def publish_state(self, state=None, pose=None, now=None, clock: bool = True) -> None:
        if state is None:
            with self.lock:
                state, pose, now = self.emulator.joint_state(), self.emulator.platform_pose(), self.emulator.time
        stamp = sim_time_msg(now)
        if clock:
            self.clock_pub.publish(Clock(clock=stamp))
        names, positions, velocities, efforts = state
        msg = JointState(name=names, position=positions.tolist(), velocity=velocities.tolist(),
                         effort=efforts.tolist())
        msg.header.stamp = stamp
        self.state_pub.publish(msg)
        self.pose_pub.publish(pose_stamped(pose, stamp))

    def publish_markers(self, pose, now) -> None:
        robot = self.emulator.robot
        rot = rotation_from_rpy(pose[3:])
        tips = pose[:3] + robot.platform_hinges @ rot.T
        stamp = sim_time_msg(now)
        legs = Marker(ns="legs", id=0, type=Marker.LINE_LIST, action=Marker.ADD)
        legs.header.frame_id, legs.header.stamp = "base", stamp
        legs.scale.x = 0.006
        legs.color.r, legs.color.g, legs.color.b, legs.color.a = 0.2, 0.5, 0.9, 1.0
        for b, a in zip(robot.base_hinges, tips, strict=True):
            legs.points += [Point(x=float(b[0]), y=float(b[1]), z=float(b[2])),
                            Point(x=float(a[0]), y=float(a[1]), z=float(a[2]))]
        ring = Marker(ns="platform", id=1, type=Marker.LINE_STRIP, action=Marker.ADD)
        ring.header.frame_id, ring.header.stamp = "base", stamp
        ring.scale.x = 0.004
        ring.color.r, ring.color.g, ring.color.b, ring.color.a = 0.9, 0.5, 0.1, 1.0
        ring.points = [Point(x=float(a[0]), y=float(a[1]), z=float(a[2])) for a in np.vstack([tips, tips[:1]])]
        self.marker_pub.publish(MarkerArray(markers=[legs, ring]))

    def shutdown(self) -> None:
        """Stop physics; the emulated robot holds its last state (nothing moves after exit)."""
        self.running = False
        self.thread.join(timeout=2.0)
        self.get_logger().info(f"stopped at sim time {self.emulator.time:.3f} s")


def main(args=None) -> None:
    run_node(HardwareEmulatorNode, args)


if __name__ == "__main__":
    main()
