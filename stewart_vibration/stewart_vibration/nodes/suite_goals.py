"""The main job's goals to the suite's action servers (rclpy, on the ``SuiteClient``'s node): kinematics'
move_to_pose, the vibration planner's vibrate (its plan, its result, its cancel) and identify_vibration_units.
Each goal is sent once and taken as accepted when the server's status lists it though its answer was lost
(``service_calls``); a planner that only says "not yet" is sent the goal again for a while. Poses (6,)
[x, y, z, roll, pitch, yaw] in m and rad in the base frame; timeouts in wall s.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from rclpy.action import ActionClient
from rclpy.node import Node

from stewart_vibration_interfaces.action import IdentifyVibrationUnits, MoveToPose, Vibrate

from ..runtime.suite_interface import IdentificationEnd, MoveResult, StepFailed, VibrationEnd, VibrationStart
from .move_messages import MOVE_ACTION, move_goal, move_result_record
from .outcomes import outcome_name
from .service_calls import GoalAcceptances, send_goal_recovering
from .vibration_goal import goal_message, plan_record

# planner refusals that only mean "not yet" (its clock or pose input has not arrived): the goal is sent again
NOT_READY_YET = ("NOT_READY", "CLOCK_NOT_RUNNING")


class SuiteGoals:
    """The goals one client sends on ``node``, waiting with its ``spin_until`` and ``wait_answer`` (the
    ``SuiteClient``'s: a wait fails at once when a node died, ``dead``)."""

    def __init__(self, node: Node, spin_until: Callable[..., None], wait_answer: Callable,
                 dead: Callable[[], list[str]]):
        self.spin_until, self._wait_answer, self.dead = spin_until, wait_answer, dead
        self.move_client = ActionClient(node, MoveToPose, MOVE_ACTION)
        self.move_acceptances = GoalAcceptances(node, MOVE_ACTION)
        self._move: dict = {}  # the latest move goal: handle, result (MoveResult)
        self.vibrate_client = ActionClient(node, Vibrate, "vibration_planner/vibrate")
        self.vibrate_acceptances = GoalAcceptances(node, "vibration_planner/vibrate")
        self.identify_client = ActionClient(node, IdentifyVibrationUnits, "vibration_planner/identify_vibration_units")
        self.identify_acceptances = GoalAcceptances(node, "vibration_planner/identify_vibration_units")
        self._vibration: dict = {}  # the latest vibrate goal: handle, plan (record), result (VibrationEnd)

    def send_move(self, pose) -> None:
        """Send the move_to_pose goal to ``pose`` (6,) once kinematics' action server is there, and wait until
        it was taken; its result arrives later (``move_result``)."""
        self.spin_until(self.move_client.server_is_ready, 30.0, f"kinematics' {MOVE_ACTION} action")
        self._move = {"result": None}
        handle = send_goal_recovering(self.move_client, move_goal(pose), self.move_acceptances, 30.0,
                                      self._wait_answer(MOVE_ACTION))
        if handle is None:
            raise StepFailed("kinematics did not take the move goal within 30 s")
        if not handle.accepted:
            raise StepFailed("kinematics rejected the move goal")
        self._move["handle"] = handle
        handle.get_result_async().add_done_callback(self._on_move_result)

    def _on_move_result(self, future) -> None:
        answer = future.result()
        if answer is not None:
            r = move_result_record(answer.result)
            self._move["result"] = MoveResult(r["outcome"], r["message"], r["position_error_m"],
                                              r["angle_error_rad"], r["peak_force_n"], r["peak_moment_nm"],
                                              r["duration_s"])

    def move_result(self) -> MoveResult | None:
        """The latest move goal's result, None while it runs (or before any)."""
        return self._move.get("result")

    def start_vibration(self, vibration: dict) -> VibrationStart:
        """Send the vibrate goal of ``vibration`` (the VIBRATION_KEYS) and wait for its plan (the first feedback)
        or its refusal (the result); sent again for up to 10 s while the planner only says "not yet"
        (NOT_READY_YET: its clock or pose estimate has not arrived)."""
        deadline = time.monotonic() + 10.0
        while True:
            self._vibration = {"plan": None, "result": None}
            handle = send_goal_recovering(self.vibrate_client, goal_message(vibration), self.vibrate_acceptances,
                                          30.0, self._wait_answer("vibration_planner/vibrate"),
                                          feedback_callback=self._on_feedback)
            if handle is None:
                raise StepFailed("the planner did not take the vibrate goal within 30 s")
            if not handle.accepted:
                return VibrationStart("INTERNAL_ERROR", "the planner rejected the goal", None)
            self._vibration["handle"] = handle
            handle.get_result_async().add_done_callback(self._on_result)
            self.spin_until(lambda: self._vibration["plan"] is not None or self._vibration["result"] is not None,
                            30.0, "the planner to start the vibration")
            result = self._vibration["result"]
            if self._vibration["plan"] is not None or result is None:
                return VibrationStart("SUCCEEDED", "started", self._vibration["plan"])
            if result.outcome not in NOT_READY_YET or time.monotonic() >= deadline:
                return VibrationStart(result.outcome, result.message, None)
            end = time.monotonic() + 0.5  # a busy machine: no /clock or pose estimate there yet
            self.spin_until(lambda e=end: time.monotonic() >= e, 1.0, "a moment")

    def _on_feedback(self, msg) -> None:
        if self._vibration.get("plan") is None:
            self._vibration["plan"] = plan_record(msg.feedback.plan)

    def _on_result(self, future) -> None:
        answer = future.result()
        if answer is None:
            return
        r = answer.result
        self._vibration["result"] = VibrationEnd(outcome_name(r.outcome.code), r.outcome.message, r.active_s,
                                                 r.cycles_delivered, int(r.loop_corrections), r.demand_correction)
        if self._vibration.get("plan") is None and r.plan.frequency_hz > 0:
            self._vibration["plan"] = plan_record(r.plan)

    def identify_units(self, frequencies_hz, output_path: str, timeout_s: float) -> IdentificationEnd:
        """Run the planner's identify_vibration_units at the current pose (``frequencies_hz``, the file
        ``output_path``) and wait for its result (sent again for up to 10 s while the planner only says "not
        yet"); StepFailed if it does not end within ``timeout_s`` (wall s)."""
        name = "vibration_planner/identify_vibration_units"
        self.spin_until(self.identify_client.server_is_ready, 30.0, f"the planner's {name} action")
        goal = IdentifyVibrationUnits.Goal(frequencies_hz=[float(f) for f in frequencies_hz], output_path=output_path)
        deadline = time.monotonic() + 10.0
        while True:
            handle = send_goal_recovering(self.identify_client, goal, self.identify_acceptances, 30.0,
                                          self._wait_answer(name))
            if handle is None or not handle.accepted:
                raise StepFailed("the planner did not take the identification goal")
            answer = handle.get_result_async()
            self.spin_until(answer.done, timeout_s, "the identification of the vibration units")
            r = answer.result().result
            end = IdentificationEnd(outcome_name(r.outcome.code), r.outcome.message, r.path, list(r.problems))
            if end.outcome not in NOT_READY_YET or time.monotonic() >= deadline:
                return end
            wait = time.monotonic() + 0.5  # a busy machine: no /clock or pose estimate there yet
            self.spin_until(lambda w=wait: time.monotonic() >= w, 1.0, "a moment")

    def vibration_result(self) -> VibrationEnd | None:
        """The latest vibrate goal's result, None while it runs (or before any)."""
        return self._vibration.get("result")

    def vibration_goal_open(self) -> bool:
        """Whether the latest vibrate goal was accepted and its result has not come (pending or running)."""
        return self._vibration.get("handle") is not None and self._vibration.get("result") is None

    def stop_vibration(self) -> bool:
        """Cancel the latest vibrate goal if it is open, waiting for its t0 or running (the units ramp out, or
        never move); whether a cancel was sent. StepFailed when the planner does not take it (a cancel lost on
        the way is sent again; a goal that ended meanwhile needs none)."""
        if not self.vibration_goal_open():
            return False
        for _ in range(3):
            future = self._vibration["handle"].cancel_goal_async()
            try:
                self.spin_until(lambda f=future: f.done() or not self.vibration_goal_open(), 5.0,
                                "the planner to take the cancel")
            except StepFailed:
                if self.dead():
                    raise
                continue
            answer = future.result() if future.done() else None
            if not self.vibration_goal_open() or (answer is not None and len(answer.goals_canceling) > 0):
                return True
        raise StepFailed("the planner did not take the cancel of the vibration (3 tries)")
