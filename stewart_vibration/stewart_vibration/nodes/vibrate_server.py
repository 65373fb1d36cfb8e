"""The vibration planner's vibrate action (stewart_vibration_interfaces/action/Vibrate): one vibration session
delivered by vibration.delivery_run.

A goal is refused at once with its outcome (the planner's start gate, vibration.settings.start_check, an
unusable pose estimate; BUSY while one runs), or started: its windows go out on the planner's
vibration/joint_trajectory, feedback at 10 Hz carries the units' state, the plan, the time since t0 and what the
sensors show delivered (analysis.delivered_from_poses over the last poses kept while it runs). Cancel = a
ramp-out over ramp_s. The run's steps (DeliveryStep) are carried out here in their order; its end sets the
planner's state and the goal's result (the outcome, the plan, the active time and the cycles delivered).
"""

from __future__ import annotations

import time
from collections import deque
from typing import cast

import numpy as np
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.task import Future

from stewart_vibration_interfaces.action import Vibrate

from ..analysis.delivered_from_poses import delivered_from_poses
from ..errors import MalformedMessageError, RefusedError, StewartError
from ..messages.joint_trajectory import encode_joint_trajectory
from ..messages.stamped import pose_from_cdr, poses_from_cdr
from ..robot import VIB_NAMES
from ..vibration.delivery_run import DeliveryRun, DeliveryStep, LoopSettings, RunEnd, start_delivery
from ..vibration.settings import start_refusal
from ..vibration.streaming import VibrationStream
from .diagnostics import ERROR, OK, WARN
from .outcomes import end_goal, outcome
from .vibration_goal import UNIT_STATES, goal_settings, plan_message

DELIVERED_WINDOW = 128  # the last samples (~0.25 s at 500 Hz) the delivered figures are judged over


class VibrateServer:
    """The vibrate action of ``node`` (a VibrationPlannerNode: its robot, parameters, clock, start gate, emulator
    report, state, window publisher, sensor subscriptions and diagnostics)."""

    def __init__(self, node):
        self.node = node
        self.run: DeliveryRun | None = None  # the vibration being delivered
        self.stream: VibrationStream | None = None  # the latest vibration's: its windows stay counted
        self.goal, self.done, self.plan_msg = None, Future(), None  # the running goal, its end, its VibrationPlan
        self.recent_poses: deque = deque(maxlen=DELIVERED_WINDOW)  # raw pose estimates, while a vibration runs
        self.action = ActionServer(node, Vibrate, "vibration_planner/vibrate", execute_callback=self.execute,
                                   goal_callback=lambda goal: GoalResponse.ACCEPT, cancel_callback=self.on_cancel)

    async def execute(self, goal_handle):
        """One vibration session: refuse it with its outcome, or run it until it ends, is cancelled or aborts."""
        node = self.node
        settings = node.settings_with(goal_settings(goal_handle.request))
        try:
            self._start(settings, goal_handle)
        except Exception as exc:  # noqa: BLE001 - every refusal (and a defect) ends the goal with its code
            if isinstance(exc, StewartError):
                name, reason = exc.outcome, str(exc) if isinstance(exc, RefusedError) else start_refusal(exc, settings)
            else:
                name, reason = "INTERNAL_ERROR", f"{type(exc).__name__}: {exc}"
                node.get_logger().error(f"vibrate goal failed: {reason}")
            return node.refused(goal_handle, Vibrate.Result(), "start", name, reason)
        plan = self.plan_msg  # this run's: another may have begun by the time its end is taken
        name, message, run = await self.done
        result = Vibrate.Result(plan=plan)
        result.outcome = outcome(name, message)
        result.active_s, result.cycles_delivered = run.delivered_dose()
        result.loop_corrections, result.demand_correction = run.loop_figures()
        end_goal(goal_handle, name)
        return result

    def _start(self, settings: dict, goal_handle) -> None:
        """Check and start the vibration of ``settings`` for ``goal_handle``; RefusedError / StewartError if not."""
        node = self.node
        now = node.check_can_start(settings["pose_timeout_s"])
        try:
            pose_stamp, pose = pose_from_cdr(cast(tuple, node.pose_data)[0], "pose estimate")
        except MalformedMessageError as exc:
            node.malformed.refuse("platform/pose_estimate", exc)
            raise RefusedError("NOT_READY", f"pose estimate unusable: {exc}") from None
        loop = LoopSettings(self._float("loop_gain"), self._float("imu_average_s"), self._float("imu_silence_s")) \
            if node.get_parameter("closed_loop").value else None
        run, first, summary = start_delivery(node.robot, pose, pose_stamp, now, settings, node.clock_rate.wall_margin,
                                             node.emulator.event_seq if node.emulator is not None else 0,
                                             node.identification, loop)
        if run.loop is not None:
            node.subscribe_sensors(units=False)
        self.run, self.stream, self.goal, self.done = run, run.stream, goal_handle, Future()
        plan = run.stream.plan
        self.plan_msg = plan_message(plan, settings, run.t0)
        node.state, node.last_error = "running", ""
        self.publish(first)
        node.get_logger().info(summary)
        node.diagnostics.set(OK, "running", frequency_hz=plan.frequency, amplitude_um=plan.amplitude * 1e6,
                             gains=np.round(plan.gains, 6).tolist(),
                             leg_amplitudes_um=np.round(plan.leg_amplitudes * 1e6, 3).tolist())
        node.report(OK, "running")

    def _float(self, name: str) -> float:
        return float(self.node.get_parameter(name).value)

    def on_cancel(self, goal_handle) -> CancelResponse:
        """Cancel = ramp out (the goal ends CANCELED when the units are at rest); a goal already ending is let be."""
        if self.run is not None and self.goal is goal_handle and self.node.state == "running":
            self.act(DeliveryStep(stop=self.run.stop(self.node.now_s())))
        return CancelResponse.ACCEPT

    def _feedback(self, run: DeliveryRun) -> None:
        """The goal's feedback: the units' state, the plan, the time since t0 and the delivered figures."""
        node = self.node
        feedback = Vibrate.Feedback(plan=self.plan_msg, elapsed_s=node.now_s() - run.t0)
        feedback.state = UNIT_STATES.get(node.emulator.state if node.emulator else "idle", 0)
        poses = poses_from_cdr(list(self.recent_poses), "pose estimate")
        delivered = delivered_from_poses(node.robot, poses.stamps, poses.values, run.stream.plan)
        if delivered.known:
            feedback.frequency_hz, feedback.delivered_amplitude_m = delivered.frequency_hz, delivered.amplitude_m
            feedback.direction_error_rad, feedback.phase_spread_rad = (delivered.direction_error_rad,
                                                                       delivered.phase_spread_rad)
        feedback.loop_corrections, feedback.demand_correction = run.loop_figures()
        self.goal.publish_feedback(feedback)

    def act(self, step: DeliveryStep) -> None:
        """Carry out a step of the running vibration, in DeliveryStep's order."""
        node = self.node
        if step.feedback:
            self._feedback(cast(DeliveryRun, self.run))
        if step.stop is not None:
            node.state = "stopping"
            if step.stop.window is not None:
                self.publish(step.stop.window)
            node.report(OK, "stopping")
            node.get_logger().info(step.stop.message)
        if step.window is not None:
            self.publish(step.window)
        if step.end is not None:
            self.end(step.end)

    def publish(self, window) -> None:
        """Send a window of the running vibration on vibration/joint_trajectory (stamped with its t0)."""
        started = time.perf_counter()
        self.node.pub.publish(encode_joint_trajectory(VIB_NAMES, cast(DeliveryRun, self.run).t0, window.times,
                                                      window.position, window.velocity, window.acceleration))
        self.node.diagnostics.values.update(windows_sent=str(cast(VibrationStream, self.stream).windows_sent),
                                            last_window_points=str(len(window.times)),
                                            last_window_encode_ms=f"{(time.perf_counter() - started) * 1e3:.2f}")

    def end(self, end: RunEnd) -> None:
        """End the running vibration: idle after it ran (or was cancelled), else aborted with the reason (its state
        until the next start)."""
        node = self.node
        if end.aborted:
            node.state, node.last_error = f"aborted: {end.message}", end.message
        else:
            node.state = "idle"
        self._finish(end.outcome, end.message)
        if end.emergency:  # one severity per call site: rclpy refuses a call site whose severity changes
            node.get_logger().error(f"vibration aborted: {end.message}")
        elif end.aborted:
            node.get_logger().warning(f"vibration aborted: {end.message}")
        node.report(OK if not end.aborted else ERROR if end.emergency else WARN, node.state)

    def _finish(self, outcome_name: str, message: str) -> None:
        """End the running goal (its execute returns the result) and forget the run."""
        run, self.run = self.run, None
        self.recent_poses.clear()
        if run is not None and not self.done.done():
            run.ended = self.node.now_s()
            self.done.set_result((outcome_name, message, run))

    def shutdown(self) -> None:
        """A vibration still running ramps out (its goal ends SHUTDOWN): the units never keep a stale stream."""
        if self.run is not None and self.node.state == "running":
            self.act(DeliveryStep(stop=self.run.stop(self.node.now_s())))
        self._finish("SHUTDOWN", "the vibration planner is shutting down: the vibration ramps out")
