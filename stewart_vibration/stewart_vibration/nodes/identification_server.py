"""The vibration planner's identify_vibration_units action (stewart_vibration_interfaces/action/
IdentifyVibrationUnits): the units' identification run (vibration.identification_runner).

The goal is checked (vibration.identification_session.identification_steps, a writable output path), then the
robot's state as for a vibration (the planner's start gate); the steps' windows go out on the planner's
vibration/joint_trajectory ahead of their start, feedback at 10 Hz names the step, and the platform IMU and the
units' sensors (legs/joint_states) are collected while it runs. The identification written is what the planner
plans with next (its identification_file parameter). Cancel = no further step, nothing written.
"""

from __future__ import annotations

import time
from typing import cast

from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.parameter import Parameter
from rclpy.task import Future

from stewart_vibration_interfaces.action import IdentifyVibrationUnits

from ..errors import StewartError
from ..messages.joint_trajectory import encode_joint_trajectory
from ..messages.stamped import pose_from_cdr
from ..output_files import writable_output
from ..robot import VIB_NAMES
from ..vibration.identification_runner import IdentificationRunner
from ..vibration.identification_session import identification_steps
from ..vibration.unit_identification import FILE_KIND
from .diagnostics import OK
from .outcomes import end_goal, outcome


class IdentificationServer:
    """The identify action of ``node`` (a VibrationPlannerNode: its robot, parameters, clock, start gate,
    window publisher and sensor subscriptions)."""

    def __init__(self, node):
        self.node = node
        self.runner: IdentificationRunner | None = None  # the run while one goes on
        self.goal = None  # its goal handle
        self.done: Future = Future()  # its end (an IdentificationEnd), which execute awaits
        self.action = ActionServer(
            node, IdentifyVibrationUnits, "vibration_planner/identify_vibration_units",
            execute_callback=self.execute, goal_callback=lambda goal: GoalResponse.ACCEPT,
            cancel_callback=lambda goal: CancelResponse.ACCEPT)

    async def execute(self, goal_handle):
        """Refuse the goal with its outcome, or run it to its end."""
        node, result = self.node, IdentifyVibrationUnits.Result()
        try:
            self._start(goal_handle)
        except StewartError as exc:
            return node.refused(goal_handle, result, "identify", exc.outcome, str(exc))
        end = await self.done
        self.runner, node.state = None, "idle"
        node.unsubscribe_unit_sensors()  # 500 Hz the planner needs only while identifying
        result.outcome, result.path, result.problems = outcome(end.outcome, end.message), end.path, end.problems
        result.duration_s = end.duration_s
        end_goal(goal_handle, end.outcome)
        node.report(OK, "idle")
        return result

    def _start(self, goal_handle) -> None:
        """Check the goal, then that the run may start now, at the current pose, and start it; StewartError if
        not."""
        node, goal = self.node, goal_handle.request
        steps, amplitude = identification_steps(tuple(goal.frequencies_hz), float(goal.amplitude_m),
                                                node.robot.vibration_unit)
        path = writable_output(goal.output_path or f"vibration_identification_{time.strftime('%Y%m%d_%H%M%S')}.yaml",
                               "vibration identification", lambda tree: tree.get("kind") == FILE_KIND)
        s = node.settings_with({})
        now = node.check_can_start(s["pose_timeout_s"])
        _, pose = pose_from_cdr(cast(tuple, node.pose_data)[0], "pose estimate")
        self.runner = IdentificationRunner.start(steps, amplitude, pose, now,
                                                 node.clock_rate.wall_margin(s["start_lead_s"]), path,
                                                 node.emulator.event_seq if node.emulator is not None else 0)
        node.state, self.goal, self.done = "identifying", goal_handle, Future()
        node.subscribe_sensors(units=True)
        node.get_logger().info(self.runner.summary)
        node.report(OK, "identifying")

    def tick(self, runner: IdentificationRunner) -> None:
        """Send the steps' windows when due, the feedback at 10 Hz, and conclude after the last step."""
        node = self.node
        step = runner.tick(node.now_s(), time.monotonic(), self.goal.is_cancel_requested, node.emulator)
        for stamp, times, position, velocity, acceleration in step.windows:
            node.pub.publish(encode_joint_trajectory(VIB_NAMES, stamp, times, position, velocity, acceleration))
        if step.progress is not None:
            number, steps, unit, frequency = step.progress
            self.goal.publish_feedback(IdentifyVibrationUnits.Feedback(step=number, steps=steps, unit=unit,
                                                                       frequency_hz=frequency))
        if step.ready:
            runner.conclude(node.robot.gravity, float(node.get_parameter("imu_average_s").value),
                            float(node.get_parameter("unit_sensor_latency_s").value))
        self.settle(runner)

    def settle(self, runner: IdentificationRunner) -> None:
        """Once the run has ended, execute takes its end (a file written is what the planner plans with next)."""
        if runner.end is not None and not self.done.done():
            if runner.end.outcome == "SUCCEEDED":
                self.node.set_parameters([Parameter("identification_file", value=runner.end.path)])
            self.done.set_result(runner.end)
