"""The hardware emulator's commands: leg trajectories (legs/joint_trajectory, answered on legs/trajectory_status),
vibration windows (vibration/joint_trajectory, answered on vibration/status) and the hardware_emulator/reset and
hardware_emulator/emergency_stop services (std_srvs/Trigger).

Commands arrive on the executor thread, are read from raw bytes only once the lifecycle allows them
(emulation.command_intake: refused unread otherwise, and when over their size limit) and are handed to the
emulator under the node's lock, which the physics thread holds while it steps. Every refusal is counted and
reported with its reason on /diagnostics; nothing here moves the robot but through the emulator's own checks.
"""

from __future__ import annotations

import math

from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from stewart_vibration_interfaces.msg import LegTrajectoryStatus

from ..emulation import command_intake
from ..emulation.command_size import LEG_TRAJECTORY, VIBRATION_WINDOW
from ..errors import StewartError
from ..messages import joint_trajectory
from .diagnostics import ERROR, OK
from .emulator_messages import leg_trajectory_status_msg


class EmulatorCommandServer:
    """The emulator node's command subscriptions and services, on ``node`` (a HardwareEmulatorNode: its
    ``emulator`` (None while unconfigured), ``lock``, ``health``, ``refusal()`` and ``publish_status``)."""

    def __init__(self, node):
        self.node = node
        self.leg_answers = command_intake.LegTrajectoryAnswers()
        node.create_subscription(JointTrajectory, "legs/joint_trajectory", self.on_leg_trajectory, 10, raw=True)
        self.trajectory_status_pub = node.create_publisher(LegTrajectoryStatus, "legs/trajectory_status", 50)
        node.create_subscription(JointTrajectory, "vibration/joint_trajectory", self.on_vibration, 50, raw=True)
        node.create_service(Trigger, "hardware_emulator/reset", self.on_reset)
        node.create_service(Trigger, "hardware_emulator/emergency_stop", self.on_emergency_stop)

    def on_leg_trajectory(self, data: bytes) -> None:
        """A leg trajectory: taken or refused; the typed answer goes to legs/trajectory_status either way."""
        node = self.node
        traj, error, end_time = None, None, math.nan
        try:
            command_intake.refuse_unread(node.refusal(), data, LEG_TRAJECTORY)
            traj = joint_trajectory.decode_joint_trajectory(data)
            end_time = command_intake.take_leg_trajectory(node.emulator, traj, node.lock)
        except StewartError as exc:
            error = exc
            node.health.reject("leg trajectory", str(exc))
        now = node.emulator.time if node.emulator is not None else 0.0
        answer = self.leg_answers.answer(traj, error, end_time, now)
        self.trajectory_status_pub.publish(leg_trajectory_status_msg(answer))
        if error is None:
            node.health.report(OK, "following leg trajectory", last_leg_trajectory_points=answer.points)

    def on_vibration(self, data: bytes) -> None:
        """A vibration window: spliced into the units' command or refused; the status says which."""
        node = self.node
        try:
            command_intake.refuse_unread(node.refusal(), data, VIBRATION_WINDOW)
            traj = joint_trajectory.decode_joint_trajectory(data)
        except StewartError as exc:
            node.health.reject("vibration command", str(exc))
            return
        report, error = command_intake.take_vibration_window(node.emulator, traj, node.lock)
        if error is not None:
            node.health.reject("vibration command", str(error))
        node.publish_status(report)

    def on_emergency_stop(self, request, response):
        """Latch the e-stop: the vibration ramps to zero, the struts brake to rest and are held until reset."""
        node = self.node
        if node.emulator is None:
            response.success, response.message = False, node.refusal()
            return response
        with node.lock:
            node.emulator.emergency_stop()
            report = node.emulator.vibration_report()[0]
        node.publish_status(report)
        node.get_logger().warning("emergency stop: vibration ramping to zero, struts braking to rest (within "
                                  "their acceleration limit), then held")
        node.health.set(ERROR, "emergency stop latched (call hardware_emulator/reset to clear)")
        response.success, response.message = True, ("vibration ramping to zero, struts braking to rest and held; "
                                                     "reset to clear")
        return response

    def on_reset(self, request, response):
        """Clear the e-stop and return home (refused with the reason while commands are not taken)."""
        node = self.node
        refusal = node.refusal()
        if refusal:
            response.success, response.message = False, refusal
            return response
        try:
            with node.lock:
                duration = node.emulator.reset()
                report = node.emulator.vibration_report()[0]
        except StewartError as exc:
            response.success, response.message = False, str(exc)
            node.health.reject("reset", str(exc))
            return response
        node.publish_status(report)
        node.health.set(OK, "reset: e-stop cleared, returning home")
        response.success = True
        response.message = f"e-stop cleared; returning home over {duration:.2f} s (sim time)"
        return response
