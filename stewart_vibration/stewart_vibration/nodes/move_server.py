"""The kinematics node's moves: the move_to_pose action (stewart_vibration_interfaces/action/MoveToPose), the
leg trajectories it sends (moves and stops) and what the robot does with them.

The goal is the target (frame base or empty, finite, a unit quaternion), a speed scale and the guard's limits
for this move (a goal may only lower them); feedback at 20 Hz (progress, time left, pose estimate, measured and
predicted load, guard state); the result has the outcome code, the residual pose error, the peak load and the
duration. Cancel = a controlled stop along the path (ForceGuard.cancel). A goal is refused with its code (BUSY
while one runs or a move is under way, beyond ``target_rate_hz``: motion.move_plan). A goal that arrives while
the struts move on their own (the way home after an e-stop reset, motion.strut_rest) waits for them to stop
before it is planned (STRUTS_NOT_AT_REST if they do not within motion.goal_keeper.REST_WAIT_S).

A move is admitted, planned and checked by motion.move_plan and sent on the node's legs/joint_trajectory
publisher; the force guard watches it from its estimated start. The stops sent are the force guard's and a
cancel's. The robot's answer to each (legs/trajectory_status) and the stops it makes itself (vibration/status:
e-stop, deactivate, shutdown, physics fault; the move is not resumed) reach the goal through the node's
subscriptions. The goal's bookkeeping and every decision about it are motion.goal_keeper's
(motion.move_goal.MoveWatch decides its end); this adapter turns the callbacks into its calls and its values
into messages.
"""

from __future__ import annotations

import time

import numpy as np
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.clock import Clock, ClockType
from rclpy.task import Future

from stewart_vibration_interfaces.action import MoveToPose
from stewart_vibration_interfaces.msg import LegTrajectoryStatus

from ..emulation.command_size import MAX_TRAJECTORY_POINTS
from ..emulation.vibration_status import STRUT_STOP_CAUSES
from ..errors import StewartError
from ..messages.status_values import vibration_report_from_cdr
from ..motion.goal_keeper import MoveSummary, RunningGoal, rest_refusal
from ..motion.guarded_move import StopPlan
from ..motion.move_goal import MoveEnd, MoveRequest
from ..motion.move_plan import MovePlanner
from ..motion.stop_planning import RECEIPT_DELAY_S
from ..motion.target_gate import TargetGate
from .diagnostics import OK, WARN, reject
from .message_conversions import duration_seconds, leg_trajectory_msg
from .move_messages import MOVE_ACTION, base_pose, move_feedback_msg, move_result_msg
from .outcomes import end_goal, outcome, outcome_name

FEEDBACK_PERIOD_S = 0.05  # wall time between a move goal's feedback messages (20 Hz)
GOAL_TOLERANCES = ("goal_position_tolerance_m", "goal_angle_tolerance_rad", "goal_time_s", "pause_timeout_s")


class MoveServer:
    """The moves of ``node`` (a KinematicsNode: its robot, tissue, force guard, goal keeper, pose estimate and
    strut lengths, struts' rest, clock, parameters, trajectory publisher and diagnostics)."""

    def __init__(self, node, target_rate_hz: float):
        self.node, self.goals, self.guard = node, node.goals, node.guard
        self.planner = MovePlanner(node.robot, node.guard, TargetGate(node.guard, target_rate_hz),
                                   MAX_TRAJECTORY_POINTS, node.tissue)
        self.goal_done: Future | None = None  # ends with the running goal (its RunningGoal)
        self.rested: Future | None = None  # ends a goal's wait for the struts (True: it goes on)
        node.create_timer(FEEDBACK_PERIOD_S, self.publish_feedback, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.action = ActionServer(node, MoveToPose, MOVE_ACTION, execute_callback=self.execute,
                                   goal_callback=lambda goal: GoalResponse.ACCEPT, cancel_callback=self.on_cancel)

    async def execute(self, goal_handle):
        """One reduction move: refused with its outcome, or followed until it succeeds, is stopped or cancelled."""
        node = self.node
        try:
            self.goals.check_free()
            goal = goal_handle.request
            request = self.goals.request(base_pose(goal.target, "target pose"), goal.speed_scale, goal.force_limit_n,
                                         goal.moment_limit_nm, node.param("speed_scale"))
            if node.pose is not None and not node.rest.at_rest():
                await self.wait_for_rest(goal_handle)
            if goal_handle.is_cancel_requested:
                goal_handle.canceled()
                return MoveToPose.Result(outcome=outcome("CANCELED", "cancelled before the move started"))
            done = self.begin(goal_handle, request)
        except Exception as exc:  # noqa: BLE001 - every refusal (and a defect) ends the goal with its code
            if isinstance(exc, StewartError):
                name, reason = exc.outcome, str(exc)
            else:
                name, reason = "INTERNAL_ERROR", f"{type(exc).__name__}: {exc}"
                node.get_logger().error(f"move goal failed: {reason}")
            reject(node, node.diagnostics, "move goal", reason)
            goal_handle.abort()
            return move_result_msg(MoveSummary(name, reason, node.pose))
        ended: RunningGoal = await done
        summary = ended.summary(node.pose)
        end_goal(goal_handle, summary.outcome)
        node.get_logger().info(f"move goal ended {summary.outcome}: {summary.message}")
        return move_result_msg(summary)

    async def wait_for_rest(self, goal_handle) -> None:
        """Until the struts are at rest, the goal is cancelled or the wait is over (then STRUTS_NOT_AT_REST)."""
        self.rested = Future()
        self.goals.wait_for_rest(goal_handle, self.node.emulator_now(), time.monotonic())
        self.node.get_logger().info("move goal: the struts are still moving on their own; it starts once they stop")
        try:
            rested = await self.rested
        finally:
            self.rested = None
            self.goals.rest_wait_over()
        if rested is False:
            raise rest_refusal(self.node.rest.speed())

    def settle_rest_wait(self, ending: bool = False) -> None:
        """End a goal's wait for the struts once it is settled (RestWait.settled; ``ending``: the node is)."""
        wait, rested = self.goals.rest_wait, self.rested
        if wait is None or rested is None or rested.done():
            return
        settled = wait.settled(self.node.rest.at_rest(), wait.handle.is_cancel_requested, ending,
                               self.node.emulator_now(), time.monotonic())
        if settled is not None:
            rested.set_result(settled)

    def begin(self, goal_handle, request: MoveRequest) -> Future:
        """Send the goal's move and follow it (the typed refusal if it cannot go); the Future ends with it."""
        node = self.node
        now = node.emulator_now()
        tolerances = tuple(node.param(name) for name in GOAL_TOLERANCES)
        self.goals.begin(goal_handle, request, node.pose, now, tolerances, self.move_to)
        self.goal_done = Future()
        # the first feedback goes out with the move, so a client sees one even for a move that ends within the
        # feedback period
        self.send_feedback(now)
        return self.goal_done

    def on_cancel(self, goal_handle) -> CancelResponse:
        """A stop along the path for the running goal; a goal still waiting for the struts ends at its next
        check."""
        node = self.node
        cancelled = self.goals.cancel(goal_handle, node.emulator_now(), node.state_time is not None)
        if cancelled is not None:
            if cancelled.stop is not None:
                self.send_stop(cancelled.stop, "cancel")
                node.get_logger().info(f"move goal cancelled: stopping over {cancelled.stop.duration:.2f} s")
            node.publish_guard_status()
        return CancelResponse.ACCEPT

    def follow(self) -> None:
        """After each batch of states (and the feedback timer): whether the running goal has ended."""
        if self.node.pose is not None:
            self.resolve(self.goals.follow(self.node.emulator_now(), self.node.pose))

    def publish_feedback(self) -> None:
        """Every FEEDBACK_PERIOD_S of wall time while a goal runs: its end if it has ended, else its feedback."""
        self.settle_rest_wait()
        self.follow()
        self.send_feedback(self.node.emulator_now())

    def send_feedback(self, now: float) -> None:
        """The running goal's feedback at ``now`` (s, robot's clock)."""
        goal, pose = self.goals.goal, self.node.pose
        if goal is not None and pose is not None:
            goal.handle.publish_feedback(move_feedback_msg(self.goals.feedback(now, pose)))

    def resolve(self, ended: RunningGoal | None) -> None:
        """The goal's execute returns its result once it has ended."""
        if ended is not None and self.goal_done is not None and not self.goal_done.done():
            self.goal_done.set_result(ended)

    def shutdown(self) -> None:
        """A goal waiting for the struts is refused and a running one ends SHUTDOWN (the robot finishes or holds
        what it was sent)."""
        self.settle_rest_wait(ending=True)
        self.resolve(self.goals.finish(MoveEnd("SHUTDOWN", "kinematics is shutting down"), self.node.emulator_now()))

    def move_to(self, request: MoveRequest) -> float:
        """Plan and send the checked move of ``request``; returns its estimated end (s, robot's clock). Raises
        the typed refusal (motion.move_plan.MovePlanner.admit, or the move's check)."""
        node, target = self.node, request.target
        goal_lengths = self.planner.admit(target, node.lengths, node.pose, node.emulator_now(), time.monotonic())
        speed = self.planner.speed(request.speed_scale)
        if speed.slowed:
            node.get_logger().warning(f"force guard: the wrench estimates lag {self.guard.estimate_lag:.3f} s behind "
                                      f"the states; this move runs at {speed.allowed * 1e3:.2f} mm/s (speed_scale "
                                      f"gives {speed.asked * 1e3:.2f}; guard_blind_travel_m "
                                      f"{self.guard.estimates.blind_travel:g})")
        plan = self.planner.trajectory(node.lengths, node.pose, goal_lengths, target, speed.value,
                                       node.param("trajectory_min_duration_s"),
                                       node.param("trajectory_sample_period_s"))
        trajectory = leg_trajectory_msg(plan.times, plan.positions, plan.velocities, plan.accelerations)
        self.goals.move_sent(request, plan.positions[-1])
        node.traj_pub.publish(trajectory)
        final = duration_seconds(trajectory.points[-1].time_from_start)
        start_time = node.emulator_now() + RECEIPT_DELAY_S
        self.guard.begin_move(start_time, final, node.lengths, goal_lengths, node.pose, target, request.force_limit,
                              request.moment_limit)
        sent = {"last_target": np.round(target, 6).tolist(), "last_duration_s": final}
        if request.guarded and not self.guard.estimates.heard:
            node.diagnostics.set(WARN, "trajectory sent UNGUARDED: no platform/external_wrench_estimate received yet "
                                 "(is leg_force_estimator running?)", **sent)
            node.get_logger().warning("force guard: no external-wrench estimate received yet; this move is unguarded")
        else:
            node.diagnostics.set(OK, "trajectory sent", **sent)
        node.get_logger().info(f"trajectory to {np.round(target, 5).tolist()} over {final:.3f} s")
        return start_time + final

    def on_trajectory_status(self, msg: LegTrajectoryStatus) -> None:
        """The robot's answer to a leg trajectory (GoalKeeper.on_trajectory_answer); the node carries it out."""
        node = self.node
        node.carry_out(self.goals.on_trajectory_answer(
            np.asarray(msg.final_positions, float), msg.accepted, msg.end_time_s, outcome_name(msg.outcome.code),
            msg.outcome.message, node.emulator_now()))

    def on_vibration_status(self, data: bytes) -> None:
        """The robot's vibration/status (raw): a stop of the struts it made itself ends the move
        (GoalKeeper.on_robot_status); a malformed status is counted and ignored."""
        node = self.node
        report = node.malformed.read("vibration/status", vibration_report_from_cdr, data)
        stop = None if report is None else self.goals.on_robot_status(
            report.fault, report.ramp_start, report.ramp_cause, report.ramp_reason, STRUT_STOP_CAUSES)
        if stop is not None:
            node.get_logger().warning(f"the emulator stopped the robot ({stop.why}): the move to {stop.target} is "
                                      "abandoned; send a new goal once it is back")
            node.publish_guard_status()

    def send_stop(self, stop: StopPlan, by: str, attempt: int = 0) -> None:
        """One-point leg trajectory: the struts come to rest at ``stop.lengths`` (by "guard" or "cancel")."""
        self.goals.stop_sent(stop.lengths, by, attempt)
        rest = np.zeros((1, 6))
        self.node.traj_pub.publish(leg_trajectory_msg([stop.duration], [stop.lengths], rest, rest))

    def resume(self) -> None:
        """Send the target a blind pause interrupted again; the goal ends if it cannot go on."""
        request = self.goals.last_target
        if request is None:  # the supervisor resumes only while there is one
            return
        node = self.node
        node.get_logger().warning("force guard: external-wrench estimates are fresh again; resuming the "
                                  f"move to {np.round(request.target, 5).tolist()}")
        node.publish_guard_status()
        try:
            self.goals.resumed(self.move_to(request))
        except StewartError as exc:  # the goal ends with why it cannot go on
            self.goals.resume_failed(exc)
