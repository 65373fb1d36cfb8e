"""kinematics node: reduction moves (an action) -> checked minimum-jerk leg trajectories; leg states -> pose
estimates; a force guard over every move.

Topics (relative): sub legs/joint_states (JointState), platform/external_wrench_estimate (WrenchStamped, the
guard's input), legs/trajectory_status (LegTrajectoryStatus: the robot's answer to each leg trajectory),
vibration/status; pub legs/joint_trajectory (JointTrajectory, leg_* absolute lengths, m),
platform/pose_estimate (PoseStamped, FK of leg_i + vib_i, one per state with its stamp; vib_i carried forward
by ``unit_sensor_latency_s``, estimation.sensed_lengths),
kinematics/guard_status (stewart_vibration_interfaces/ForceGuardStatus, reliable + transient local: the force
guard armed or tripped, with its limits, the trip's figures and the peak load since).
Action kinematics/move_to_pose (MoveToPose): the goal is the target (frame base or empty, finite, a unit
quaternion), a speed scale and the guard's limits for this move (a goal may only lower them); feedback at
20 Hz (progress, time left, pose estimate, measured and predicted load, guard state); the result has the
outcome code, the residual pose error, the peak load and the duration (motion.move_goal decides the end).
Cancel = a controlled stop along the path (ForceGuard.cancel). A goal is refused with its code (BUSY while
one runs or a move is under way, beyond ``target_rate_hz``: motion.target_gate). A goal that arrives while
the struts move on their own (the way home after an e-stop reset, motion.strut_rest) waits for them to stop
before it is planned (STRUTS_NOT_AT_REST if they do not within REST_WAIT_S).
Action kinematics/calibrate (Calibrate): a kinematic calibration run that writes a calibrated robot file
(nodes.calibration_server); platform/tracker_pose is read for it, kinematics/calibration_samples published.
Services: kinematics/plan_path (PlanPath: a checked path through waypoints, nothing moves), kinematics/reset_guard
(std_srvs/Trigger).
Diagnostics on /diagnostics, with the state stream's health (received, lost,
processed, lag); ERROR while the force guard is tripped. States arrive raw and are solved in vectorised
batches of ``batch_size`` (the emulator's bursts) or every ``batch_period_s`` (wall clock; FK
warm-started from the previous pose); wrench estimates likewise.
Malformed messages on the raw inputs (states, wrench estimates, vibration/status) are ignored, counted on
/diagnostics (``malformed <input>``) and logged rate-limited (nodes.diagnostics.MalformedInputs).

Soft tissue: with ``tissue_config`` every target and plan_path request is also checked for the strut
forces it needs under that tissue model (motion.paths.check_path_forces: quasi-static Newton-Euler +
the tissue's elastic wrench), refused with the leg and the waypoint above strut_force_max_n.
Force guard (stewart_vibration.motion.force_guard): during a move the external-wrench estimate is watched
(subscribed for good; between moves only the newest of each batch is decoded); when the force
(moment) at the end of a stop commanded now would exceed ``guard_force_n`` (``guard_moment_nm``) the
struts are stopped smoothly along the planned path (a one-point trajectory within
guard_deceleration_scale x strut_acceleration_max), the node holds there, reports ERROR and refuses
goals further in that direction (GUARD_BLOCKED) until kinematics/reset_guard or a new limit.
The guard is asked on every batch of estimates and of states (the states move the prediction on). A
move also stops (limit "estimates") when the newest wrench estimate is more than
``guard_max_estimate_age_s`` behind the newest joint state: the estimator is late, stalled or gone, the
guard blind. That is a pause: once the stop is over and estimates are fresh again, the node sends the same
target again, unless the load passed a limit meanwhile (then the trip is a latched force trip).
"""

from __future__ import annotations

import time
from typing import cast

import numpy as np
from geometry_msgs.msg import PoseStamped, Wrench, WrenchStamped
from nav_msgs.msg import Path
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.task import Future
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from stewart_vibration_interfaces.action import MoveToPose
from stewart_vibration_interfaces.msg import ForceGuardStatus, LegTrajectoryStatus, VibrationUnitsStatus
from stewart_vibration_interfaces.srv import PlanPath

from ..dynamics.tissue_config import load_tissue_option
from ..emulation.command_size import MAX_TRAJECTORY_POINTS
from ..emulation.vibration_status import STRUT_STOP_CAUSES
from ..errors import InvalidInputError, MalformedMessageError, RefusedError, StewartError
from ..estimation.sensed_lengths import sensed_leg_lengths
from ..kinematics import check_pose, forward_kinematics
from ..kinematics.robot_config import load_robot
from ..kinematics.rotations import pose_to_position_quaternion
from ..kinematics.workspace import check_strut_path
from ..messages.fields import BASE_FRAME
from ..messages.joint_states import JointStateDecoder, decode_joint_states_dropping_malformed
from ..messages.stamped import MAX_JOINT_POSITION_M, rows_within, wrenches_from_cdr
from ..messages.stamped_doubles import PoseStampedEncoder
from ..messages.status_values import vibration_report_from_cdr
from ..messages.stream_health import StreamHealth
from ..motion.force_guard import ForceGuard
from ..motion.guard_status import GUARD_STATES
from ..motion.guard_supervisor import GuardSupervisor, PublishStatus, ResumeTarget, SendStop, Tripped
from ..motion.guarded_move import StopPlan
from ..motion.move_goal import MoveEnd, MoveRequest, MoveWatch, move_request, pose_errors
from ..motion.paths import check_path_forces, checked_path, interpolate_poses
from ..motion.profiles import minimum_jerk, minimum_jerk_duration
from ..motion.stop_planning import RECEIPT_DELAY_S
from ..motion.strut_rest import StrutRest
from ..motion.target_gate import TargetGate
from ..parameters.tables import KINEMATICS
from ..robot import LEG_NAMES
from .calibration_server import CalibrationServer
from .diagnostics import ERROR, OK, WARN, Diagnostics, MalformedInputs, reject
from .message_conversions import JointColumns, RawBatcher, duration_msg, duration_seconds, emulator_now, pose_stamped
from .move_messages import base_pose
from .node_parameters import declare_table
from .outcomes import outcome, outcome_name, outcome_of
from .run_loop import STATUS_QOS, STREAM_DEPTH, run_node
from .status_messages import guard_status_msg

FEEDBACK_PERIOD_S = 0.05  # wall time between a move goal's feedback messages (20 Hz)
REST_WAIT_S = 60.0  # a goal waits this long (robot's clock) for struts moving on their own to stop
REST_WAIT_WALL_S = 120.0  # ... and at most this long on the wall clock (no states: the robot is gone)
GUARD_PARAMS = ("guard_force_n", "guard_moment_nm", "guard_deceleration_scale", "guard_max_estimate_age_s",
                "guard_blind_travel_m")


class GuardedDiagnostics(Diagnostics):
    """The node's status: never better than ERROR while the force guard is tripped, its reason first."""

    guard: ForceGuard | None = None

    def set(self, level, message: str, **values) -> None:
        if self.guard is not None and self.guard.tripped:
            level = ERROR
            if not message.startswith("force guard"):
                message = f"force guard {self.guard.message()}; {message}"
        super().set(level, message, **values)


class KinematicsNode(Node):
    """Thin adapter over stewart_vibration.kinematics, motion_profiles and force_guard."""

    def __init__(self):
        super().__init__("kinematics")
        params = declare_table(self, KINEMATICS)
        period, batch_size, target_rate = params["batch_period_s"], params["batch_size"], params["target_rate_hz"]
        path = self.get_parameter("robot_config").value
        self.robot = load_robot(path or None)
        self.tissue = load_tissue_option(self.get_parameter("tissue_config").value, self.robot)
        param = self.get_parameter
        self.guard = ForceGuard(self.robot, param("guard_force_n").value, param("guard_moment_nm").value,
                                param("guard_deceleration_scale").value, param("guard_max_estimate_age_s").value,
                                param("guard_blind_travel_m").value)
        self.supervisor = GuardSupervisor(self.guard, period)
        self.unit_latency = float(self.get_parameter("unit_sensor_latency_s").value)
        self.state_time = None  # stamp of the newest joint state (the emulator's clock), s
        self.diagnostics = GuardedDiagnostics(self, "kinematics")
        self.diagnostics.guard = self.guard
        self.malformed = MalformedInputs(self, self.diagnostics)
        self.target_gate = TargetGate(self.guard, target_rate)
        self.lengths = None  # latest leg_* (strut) lengths, m
        self.rest = StrutRest()
        self.rest_wait: tuple | None = None  # a goal waiting for the struts to stop: handle, Future, sim and wall
        # deadlines (s)
        self.pose = None  # latest pose estimate
        self.fk_failures = 0
        self.health = StreamHealth()
        self.columns = JointColumns()
        self.decoder = JointStateDecoder()
        self.pose_encoder = PoseStampedEncoder(BASE_FRAME)
        self.batcher = RawBatcher(self, batch_size, period, self.process)
        self.traj_pub = self.create_publisher(JointTrajectory, "legs/joint_trajectory", 10)
        self.pose_pub = self.create_publisher(PoseStamped, "platform/pose_estimate", STREAM_DEPTH)
        self.diagnostics.report_readers("platform/pose_estimate", self.pose_pub)
        # 1 s of states at 500 Hz: under CPU load the executor stalls > 0.1 s and depth 50 lost estimates
        self.create_subscription(JointState, "legs/joint_states", self.batcher.add, STREAM_DEPTH, raw=True)
        self.create_timer(1.0, self.report, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.diagnostics.watch("legs/joint_states", 1.0, "from hardware_emulator")
        self.create_service(PlanPath, "kinematics/plan_path", self.on_plan_path)
        self.wrench_decoder_errors = 0
        self.wrench_batcher = RawBatcher(self, batch_size, period, self.process_wrenches)
        # subscribed for good: a subscription made when a move starts is blind until DDS has matched it
        # (seconds on a busy machine: a guarded move once ran to its target unwatched)
        self.create_subscription(WrenchStamped, "platform/external_wrench_estimate", self.wrench_batcher.add,
                                 STREAM_DEPTH, raw=True)
        self.guard_pub = self.create_publisher(ForceGuardStatus, "kinematics/guard_status", STATUS_QOS)
        self.sent_move: np.ndarray | None = None  # the final leg lengths of the last move sent (its key)
        self.sent_stop: tuple[np.ndarray, str, int] | None = None  # the last stop sent: lengths, by whom, attempt
        self.last_target: MoveRequest | None = None  # the move goal's request (resumed after a blind stop)
        self.goal: dict | None = None  # the running move goal: handle, done (Future of MoveEnd), watch, peak,
        # start (s), duration (s)
        self.create_subscription(LegTrajectoryStatus, "legs/trajectory_status", self.on_trajectory_status, 50)
        # the emulator's own stops (e-stop, deactivate, shutdown, physics fault) end the move: never resumed
        self.create_subscription(VibrationUnitsStatus, "vibration/status", self.on_vibration_status, STATUS_QOS,
                                 raw=True)
        self.robot_stop_seen: tuple | None = None  # (ramp_start, ramp_cause, fault) of the last stop acted on
        self.create_service(Trigger, "kinematics/reset_guard", self.on_reset_guard)
        self.create_timer(FEEDBACK_PERIOD_S, self.publish_goal_feedback, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.action = ActionServer(self, MoveToPose, "kinematics/move_to_pose", execute_callback=self.execute,
                                   goal_callback=lambda goal: GoalResponse.ACCEPT, cancel_callback=self.on_cancel)
        self.calibration = CalibrationServer(self)
        self.add_post_set_parameters_callback(self.on_parameters_set)
        self.publish_guard_status()
        self.diagnostics.set(OK, "waiting for legs/joint_states")
        self.waiting_for_states = True  # until the first state: then "tracking", unless a warning was set meanwhile
        self.get_logger().info(f"kinematics ready (robot {self.robot.source}, tissue "
                               f"{self.tissue.source if self.tissue else 'none'}; {self.guard.message()})")

    # -- state estimate ---------------------------------------------------
    def process(self, messages: list, arrivals: np.ndarray) -> None:
        """Solve FK for a batch of states (one batch per layout) and publish one estimate each."""
        self.diagnostics.seen("legs/joint_states")
        batches, kept = decode_joint_states_dropping_malformed(
            messages, self.decoder, lambda reason: self._malformed(MalformedMessageError(reason)))
        arrivals = arrivals[kept]
        first = 0
        for batch in batches:
            n = len(batch.stamps)
            self._solve(batch, arrivals[first:first + n])
            first += n

    def _malformed(self, error: MalformedMessageError, count: int = 1) -> None:
        self.malformed.refuse("legs/joint_states", error, count)
        self.health.rejected += count

    def _solve(self, batch, arrivals) -> None:
        self.health.arrived(batch.stamps)
        legs_at, vib_at = self.columns(batch.names)
        if legs_at is None:
            self._malformed(MalformedMessageError(f"joint state names {list(batch.names)[:14]} lack one of "
                                                  f"{list(LEG_NAMES)} or repeat one", field="name", kind="names"),
                            len(batch.stamps))
            return
        legs = batch.position[:, legs_at]
        lengths = sensed_leg_lengths(legs, batch.position[:, vib_at] if vib_at is not None else None,
                                     batch.velocity[:, vib_at] if vib_at is not None else None, self.unit_latency)
        good = rows_within(lengths, MAX_JOINT_POSITION_M)
        if not good.all():
            self._malformed(MalformedMessageError(f"leg positions not finite or beyond {MAX_JOINT_POSITION_M:g} m (or "
                                                  "fewer positions than names)", field="position", kind="not_finite"),
                            int((~good).sum()))
            if not good.any():
                return
        lengths, stamps, arrivals, legs = lengths[good], batch.stamps[good], arrivals[good], legs[good]
        guess = self.robot.home_pose if self.pose is None else self.pose
        try:
            result = forward_kinematics(self.robot, lengths, guess=np.broadcast_to(guess, lengths.shape),
                                        check_limits=False)
        except StewartError as exc:
            self._malformed(MalformedMessageError(f"joint state: {exc}", field="position", kind="range"), len(lengths))
            return
        ok = result.converged & result.assembly_ok
        if not ok.all():
            self.fk_failures += int((~ok).sum())
            self.diagnostics.set(WARN, "forward kinematics did not converge", fk_failures=self.fk_failures)
            if not ok.any():
                self.pose = None  # cold start next time
                return
        poses = result.pose[ok]
        position, quaternion = pose_to_position_quaternion(poses)
        for stamp, p, q in zip(stamps[ok], position, quaternion, strict=True):
            self.pose_pub.publish(self.pose_encoder.encode(stamp, p, q))
        self.health.done(arrivals[ok], time.monotonic())
        self.lengths, self.pose = legs[ok][-1], poses[-1]
        self.state_time = float(stamps[-1])
        self.rest.observe(stamps[ok], legs[ok])
        self.settle_rest_wait()
        self.calibration.on_states(stamps[ok], lengths[ok])
        self.supervisor.states_read(stamps, legs)
        # estimates already queued here are newer news than their absence: after a stall of this node the
        # states are taken first, and judging the guard blind before reading them would stop for nothing
        self.wrench_batcher.flush()
        self.carry_out(self.supervisor.on_states(self.emulator_now(), self.state_time))
        if self.waiting_for_states:
            self.waiting_for_states = False
            if self.diagnostics.level == OK:
                self.diagnostics.set(OK, "tracking")
        self.follow_goal()

    def report(self) -> None:
        self.diagnostics.values.update(self.health.values("states"))
        if self.health.behind:
            p99 = self.health.lag_percentiles_ms()[1]
            self.diagnostics.set(WARN, f"falling behind: {self.health.lost} states lost, lag p99 {p99:.1f} ms")
        self.diagnostics.publish()

    # -- force guard -------------------------------------------------------
    def process_wrenches(self, messages: list, arrivals: np.ndarray) -> None:
        """Wrench estimates: the guard's input (the newest only when it watches no move)."""
        if self.guard.move is None and self.goal is None:
            messages = messages[-1:]
        batch = wrenches_from_cdr(messages, "external wrench estimate")
        for error in batch.errors:
            self.wrench_decoder_errors += 1
            self.malformed.refuse("platform/external_wrench_estimate", error)
        if not len(batch.kept):
            return
        stamps, wrenches = batch.stamps, batch.values
        if self.goal is not None:  # the goal's peak load (N, N m)
            peak = self.goal["peak"]
            peak[0] = max(peak[0], float(np.linalg.norm(wrenches[:, :3], axis=1).max()))
            peak[1] = max(peak[1], float(np.linalg.norm(wrenches[:, 3:], axis=1).max()))
        self.carry_out(self.supervisor.on_wrenches(stamps, wrenches, self.emulator_now(stamps[-1]), self.state_time,
                                                   self.last_target is not None))

    def carry_out(self, actions: list) -> None:
        """Do what the guard's supervisor decided: send stops, report trips, publish its status, resume."""
        for action in actions:
            if isinstance(action, SendStop):
                if action.why:
                    self.get_logger().error(f"{action.why}; stopping again over {action.stop.duration:.2f} s")
                self.send_stop(action.stop, action.by, action.attempt)
            elif isinstance(action, Tripped):
                self.on_trip(action.trip, held=action.held)
            elif isinstance(action, PublishStatus):
                self.publish_guard_status()  # the stop is over: its peak load
            elif isinstance(action, ResumeTarget):
                self.resume_target()

    def resume_target(self) -> None:
        """Send the target a blind pause interrupted again; the goal ends if it cannot go on."""
        request = self.last_target
        if request is None:  # the supervisor resumes only while there is one
            return
        self.get_logger().warning("force guard: external-wrench estimates are fresh again; resuming the "
                                  f"move to {np.round(request.target, 5).tolist()}")
        self.publish_guard_status()
        try:
            end = self.move_to(request)
            if self.goal is not None:
                self.goal["watch"].moving(end)
        except StewartError as exc:  # the goal ends with why it cannot go on
            self.last_target = None
            if self.goal is not None:
                self.goal["watch"].end(exc.outcome, f"the move could not resume after a pause: {exc}")

    def emulator_now(self, fallback: float = 0.0) -> float:
        """The emulator's time as best known here (s): see nodes.message_conversions.emulator_now."""
        return emulator_now(self, self.state_time, fallback)

    def on_trip(self, trip, held: bool = False) -> None:
        """Report a trip (ERROR, guard status; its stop was sent) and tell the move goal: a force or moment trip
        ends it GUARD_STOPPED once the struts are at rest (now, when an earlier stop ``held`` them already), a
        trip for late estimates pauses it."""
        message = self.guard.message()
        if self.goal is not None:
            now = self.emulator_now()
            end = trip.stop.receipt_time + trip.stop.duration if trip.stop is not None else \
                (self.guard.move.end if self.guard.move is not None else now)
            if held:
                end = now
            why = "PAUSED" if trip.which == "estimates" else "GUARD_STOPPED"
            self.goal["watch"].stopping(why, end, now, f"force guard {message}")
        self.get_logger().error(f"force guard {message}")
        self.diagnostics.set(ERROR, f"force guard {message}")
        self.publish_guard_status()

    def on_trajectory_status(self, msg: LegTrajectoryStatus) -> None:
        """The robot's answer to a leg trajectory, matched to what this node sent by its final lengths: a
        refused stop is planned again over a wider window (a trip's by the guard, a cancel's likewise); a
        refused move ends the goal (ROBOT_REFUSED, or the robot's own code when it cannot move now: e-stop,
        inactive); a taken move gives the goal the move's end."""
        final = np.asarray(msg.final_positions, float)
        stop, move, goal = self.sent_stop, self.sent_move, self.goal
        if stop is not None and np.array_equal(final, stop[0]):
            if msg.accepted:
                return
            _lengths, by, attempt = stop
            now = self.emulator_now()
            actions = self.supervisor.on_stop_refused(by, attempt, now, msg.outcome.message)
            self.carry_out(actions)
            for retry in actions:
                if isinstance(retry, SendStop) and goal is not None and by == "cancel":
                    goal["watch"].stopping("CANCELED", retry.stop.receipt_time + retry.stop.duration, now,
                                           "cancelled: the struts stopped")
            return
        if move is None or not np.array_equal(final, move) or goal is None:
            return
        if msg.accepted:
            if goal["watch"].phase == "moving" and np.isfinite(msg.end_time_s):
                goal["watch"].moving(msg.end_time_s)
            return
        self.guard.robot_stopped()
        self.last_target = None
        name = outcome_name(msg.outcome.code)
        name = name if name in ("ESTOP_LATCHED", "ROBOT_INACTIVE") else "ROBOT_REFUSED"
        goal["watch"].end(name, f"the robot refused the move: {msg.outcome.message}")
        self.publish_guard_status()

    def on_vibration_status(self, data: bytes) -> None:
        """The emulator's vibration/status (raw): a stop of the struts it made itself (STRUT_STOP_CAUSES, or a latched
        physics fault) ends kinematics' move -- the guard drops it and the target is not resumed after a pause;
        a new target is needed once the robot is back (reset). A malformed status is counted and ignored."""
        report = self.malformed.read("vibration/status", vibration_report_from_cdr, data)
        if report is None:
            return
        stopped = report.fault or (report.ramp_start is not None and report.ramp_cause in STRUT_STOP_CAUSES)
        key = (report.ramp_start, report.ramp_cause, report.fault)
        if not stopped or key == self.robot_stop_seen:
            return
        self.robot_stop_seen = key
        dropped = self.guard.robot_stopped()
        request, self.last_target = self.last_target, None
        why = f"physics fault: {report.fault}" if report.fault else report.ramp_reason
        if self.goal is not None:
            name = "PHYSICS_FAULT" if report.fault else "EMERGENCY_STOPPED" if report.ramp_cause == "emergency_stop" \
                else "STOPPED_EARLY"
            self.goal["watch"].end(name, f"the robot stopped the move itself ({why})")
        if dropped or request is not None:
            target = None if request is None else np.round(request.target, 5).tolist()
            self.get_logger().warning(f"the emulator stopped the robot ({why}): the move to {target} is abandoned; "
                                      "send a new goal once it is back")
            self.publish_guard_status()

    def send_stop(self, stop: StopPlan, by: str, attempt: int = 0) -> None:
        """One-point leg trajectory (stamp 0 = now): the struts come to rest at ``stop.lengths``. ``by``: "guard"
        (a trip's stop) or "cancel"; ``attempt``: how many refused stops came before it."""
        self.sent_stop = (np.array(stop.lengths, float), by, attempt)
        msg = JointTrajectory()
        msg.header.stamp.sec, msg.header.stamp.nanosec = 0, 0
        msg.joint_names = list(LEG_NAMES)
        point = JointTrajectoryPoint()
        point.positions = stop.lengths.tolist()
        point.velocities = [0.0] * 6
        point.accelerations = [0.0] * 6
        point.time_from_start = duration_msg(stop.duration)
        msg.points.append(point)
        self.traj_pub.publish(msg)

    def publish_guard_status(self) -> None:
        self.guard_pub.publish(guard_status_msg(self.guard.status(), self.get_clock().now().to_msg()))

    def on_reset_guard(self, request, response):
        was = self.guard.reset()
        response.success = True
        response.message = "force guard reset: goals in every direction accepted again" if was else \
            "the force guard was not tripped (nothing to reset)"
        self.get_logger().info(response.message)
        self.diagnostics.set(OK, response.message)
        self.publish_guard_status()
        return response

    def on_parameters_set(self, params) -> None:
        """After a set (validated by the table's check): guard_* take effect at once; a changed limit clears a
        trip (the operator's decision)."""
        values = {p.name: float(p.value) for p in params if p.name in GUARD_PARAMS}
        if not values:
            return
        if "guard_blind_travel_m" in values:
            self.guard.estimates.blind_travel = values["guard_blind_travel_m"]
        if "guard_max_estimate_age_s" in values:
            self.guard.estimates.max_estimate_age = values["guard_max_estimate_age_s"]
        if "guard_deceleration_scale" in values:
            self.guard.deceleration_scale = values["guard_deceleration_scale"]
        cleared = self.guard.set_limits(values.get("guard_force_n"), values.get("guard_moment_nm"))
        if cleared:
            self.get_logger().info("force guard: new limit, trip cleared")
            self.diagnostics.set(OK, "force guard: new limit, trip cleared")
        self.publish_guard_status()

    # -- the move_to_pose action -------------------------------------------------------------
    async def execute(self, goal_handle):
        """One reduction move: refused with its outcome, or followed until it succeeds, is stopped or cancelled."""
        try:
            request = self.check_goal(goal_handle)
            if self.pose is not None and not self.rest.at_rest():
                await self.wait_for_rest(goal_handle)
            if goal_handle.is_cancel_requested:
                goal_handle.canceled()
                return MoveToPose.Result(outcome=outcome("CANCELED", "cancelled before the move started"))
            self.begin_goal(goal_handle, request)
        except Exception as exc:  # noqa: BLE001 - every refusal (and a defect) ends the goal with its code
            if isinstance(exc, StewartError):
                name, reason = exc.outcome, str(exc)
            else:
                name, reason = "INTERNAL_ERROR", f"{type(exc).__name__}: {exc}"
                self.get_logger().error(f"move goal failed: {reason}")
            reject(self, self.diagnostics, "move goal", reason)
            goal_handle.abort()
            result = MoveToPose.Result()
            result.outcome = outcome(name, reason)
            if self.pose is not None:
                result.final_pose = pose_stamped(self.pose, self.get_clock().now().to_msg()).pose
            return result
        goal = cast(dict, self.goal)
        end: MoveEnd = await goal["done"]
        result = MoveToPose.Result(outcome=outcome(end.outcome, end.message), duration_s=goal["duration"])
        if self.pose is not None:
            result.final_pose = pose_stamped(self.pose, self.get_clock().now().to_msg()).pose
            result.position_error_m, result.angle_error_rad = pose_errors(self.pose, goal["request"].target)
        result.peak_force_n, result.peak_moment_nm = goal["peak"]
        if end.outcome == "SUCCEEDED":
            goal_handle.succeed()
        elif end.outcome == "CANCELED" and goal_handle.is_cancel_requested:
            goal_handle.canceled()
        else:
            goal_handle.abort()
        self.get_logger().info(f"move goal ended {end.outcome}: {end.message}")
        return result

    def check_goal(self, goal_handle) -> MoveRequest:
        """The MoveToPose goal's request, checked on its own (frame, values, the pose); RefusedError /
        StewartError with the outcome if not (BUSY while another goal runs or waits)."""
        if self.goal is not None or self.rest_wait is not None:
            raise RefusedError("BUSY", "another move goal is running: cancel it or wait for its result")
        request_msg = goal_handle.request
        target = base_pose(request_msg.target, "target pose")
        param = self.get_parameter
        request = move_request(target, request_msg.speed_scale, request_msg.force_limit_n, request_msg.moment_limit_nm,
                               param("speed_scale").value, self.guard.force_limit, self.guard.moment_limit)
        check_pose(self.robot, target)
        return request

    async def wait_for_rest(self, goal_handle) -> None:
        """Until the struts are at rest (motion.strut_rest), the goal is cancelled or REST_WAIT_S passed; raises
        RefusedError STRUTS_NOT_AT_REST in the last case."""
        done = Future()
        self.rest_wait = (goal_handle, done, self.emulator_now() + REST_WAIT_S, time.monotonic() + REST_WAIT_WALL_S)
        self.get_logger().info("move goal: the struts are still moving on their own; it starts once they stop")
        try:
            rested = await done
        finally:
            self.rest_wait = None
        if rested is False:
            speed = self.rest.speed()
            drift = "" if speed is None else f" (the fastest drifts at {speed * 1e3:.3f} mm/s)"
            raise RefusedError("STRUTS_NOT_AT_REST", f"the struts did not come to rest within {REST_WAIT_S:g} s"
                               f"{drift}: a move is planned from rest; send it again once the robot has stopped")

    def settle_rest_wait(self, ending: bool = False) -> None:
        """End the wait of a goal for the struts: True at rest or cancelled, False past a deadline or ``ending``."""
        if self.rest_wait is None:
            return
        handle, done, sim_deadline, wall_deadline = self.rest_wait
        if done.done():
            return
        if self.rest.at_rest() or handle.is_cancel_requested:
            done.set_result(True)
        elif ending or self.emulator_now() > sim_deadline or time.monotonic() > wall_deadline:
            done.set_result(False)

    def begin_goal(self, goal_handle, request: MoveRequest) -> None:
        """Send the checked move of a MoveToPose goal; RefusedError / StewartError with the outcome if not."""
        if self.pose is None:
            raise RefusedError("NOT_READY", "no legs/joint_states received yet (is the hardware emulator running?)")
        param = self.get_parameter
        target = request.target
        start_pose, now = self.pose.copy(), self.emulator_now()
        watch = MoveWatch(start_pose, target, param("goal_position_tolerance_m").value,
                          param("goal_angle_tolerance_rad").value, param("goal_time_s").value,
                          param("pause_timeout_s").value)
        end = self.move_to(request)
        watch.moving(end)
        self.goal = {"handle": goal_handle, "done": Future(), "watch": watch, "request": request, "peak": [0.0, 0.0],
                     "start": now, "duration": 0.0}
        # the first feedback goes out with the move, so a client sees one even for a move that ends within the
        # feedback period
        goal_handle.publish_feedback(self.feedback(watch, now))

    def on_cancel(self, goal_handle) -> CancelResponse:
        """Cancel = a controlled stop along the path within guard_deceleration_scale x strut_acceleration_max;
        the goal ends CANCELED once the struts are at rest (a goal whose move ends first ends at its end)."""
        goal = self.goal
        if goal is None or goal["handle"] is not goal_handle:
            return CancelResponse.ACCEPT  # a goal still waiting for the struts to stop ends at the next check
        self.last_target = None  # a paused move is not resumed
        now = self.emulator_now()
        watch = goal["watch"]
        stop = self.guard.cancel(now) if self.state_time is not None else None
        if stop is not None:
            self.send_stop(stop, "cancel")
            watch.stopping("CANCELED", stop.receipt_time + stop.duration, now,
                           f"cancelled: the struts stopped over {stop.duration:.2f} s")
            self.get_logger().info(f"move goal cancelled: stopping over {stop.duration:.2f} s")
        else:
            end = watch.until if watch.phase == "moving" else now
            watch.stopping("CANCELED", end, now, "cancelled: the move ended before a stop could")
        self.publish_guard_status()
        return CancelResponse.ACCEPT

    def follow_goal(self) -> None:
        """After each batch of states (and the feedback timer): whether the running goal has ended."""
        goal = self.goal
        if goal is None or self.pose is None:
            return
        end = goal["watch"].update(self.emulator_now(), self.pose)
        if end is not None:
            self.finish_goal(end)

    def publish_goal_feedback(self) -> None:
        """Every FEEDBACK_PERIOD_S of wall time while a goal runs: its end if it has ended, else its feedback."""
        self.settle_rest_wait()
        self.follow_goal()
        goal = self.goal
        if goal is not None and self.pose is not None:
            goal["handle"].publish_feedback(self.feedback(goal["watch"], self.emulator_now()))

    def feedback(self, watch: MoveWatch, now: float) -> MoveToPose.Feedback:
        """The goal's feedback now: progress, time left, the pose estimate, the load and the guard's state."""
        pose = cast(np.ndarray, self.pose)
        msg = MoveToPose.Feedback(progress=watch.progress(pose), time_remaining_s=watch.time_remaining(now))
        msg.pose_estimate = pose_stamped(pose, self.get_clock().now().to_msg()).pose
        w = self.guard.last_wrench
        msg.measured_load = Wrench()
        msg.measured_load.force.x, msg.measured_load.force.y, msg.measured_load.force.z = (float(v) for v in w[:3])
        msg.measured_load.torque.x, msg.measured_load.torque.y, msg.measured_load.torque.z = (float(v) for v in w[3:])
        msg.predicted_force_n, msg.predicted_moment_nm = self.guard.predicted
        msg.guard_state = GUARD_STATES.index(self.guard.status().state)
        return msg

    def finish_goal(self, end: MoveEnd) -> None:
        """End the running goal (its execute returns the result) and forget it."""
        goal, self.goal = self.goal, None
        if goal is None or goal["done"].done():
            return
        if end.outcome != "SUCCEEDED":
            self.last_target = None
        goal["duration"] = self.emulator_now() - goal["start"]
        goal["done"].set_result(end)

    def shutdown(self) -> None:
        """A goal still running ends SHUTDOWN (the robot finishes or holds what it was sent)."""
        self.settle_rest_wait(ending=True)
        self.calibration.shutdown()
        self.finish_goal(MoveEnd("SHUTDOWN", "kinematics is shutting down"))

    def move_to(self, request: MoveRequest) -> float:
        """Plan and send the checked move of ``request`` (target (6,) m, rad; base); returns its estimated end
        (s, robot's clock). Raises the typed refusal when the pose or the path is infeasible, the guard blocks
        that direction, a move is pending or under way, or moves come faster than target_rate_hz."""
        target = request.target
        goal_lengths = check_pose(self.robot, target)
        if self.lengths is None or self.pose is None:
            raise RefusedError("NOT_READY", "no legs/joint_states received yet")
        self.guard.check_target(self.pose, target)
        refusal = self.target_gate.refusal(self.emulator_now(), time.monotonic())
        if refusal is not None:
            raise RefusedError("BUSY", refusal)
        trajectory = self.plan_trajectory(self.lengths, self.pose, goal_lengths, target, request.speed_scale)
        self.sent_move = np.array(trajectory.points[-1].positions, float)
        self.traj_pub.publish(trajectory)
        self.last_target = request
        final = duration_seconds(trajectory.points[-1].time_from_start)
        start_time = self.emulator_now() + RECEIPT_DELAY_S
        self.guard.begin_move(start_time, final, self.lengths, goal_lengths, self.pose, target,
                              request.force_limit, request.moment_limit)
        if not self.guard.estimates.heard and (request.force_limit > 0 or request.moment_limit > 0):
            self.diagnostics.set(WARN, "trajectory sent UNGUARDED: no platform/external_wrench_estimate received yet "
                                 "(is leg_force_estimator running?)", last_target=np.round(target, 6).tolist(),
                                 last_duration_s=final)
            self.get_logger().warning("force guard: no external-wrench estimate received yet; this move is unguarded")
        else:
            self.diagnostics.set(OK, "trajectory sent", last_target=np.round(target, 6).tolist(),
                                 last_duration_s=final)
        self.get_logger().info(f"trajectory to {np.round(target, 5).tolist()} over {final:.3f} s")
        return start_time + final

    def plan_trajectory(self, start_lengths, start_pose, goal_lengths, goal_pose, speed_scale: float
                        ) -> JointTrajectory:
        """Minimum-jerk leg trajectory (at most MAX_TRAJECTORY_POINTS points), checked along the whole move for what
        the six struts do together (``kinematics.workspace.check_strut_path``: FK, joints, conditioning, the
        emulator's check too) and, with a tissue model, for the strut forces it needs (the waypoints are the
        trajectory's samples)."""
        speed = self.robot.limits.strut_velocity_max * speed_scale
        guarded = self.guard.speed_limit()  # slower while the wrench estimates lag (busy machine)
        if guarded < speed:
            self.get_logger().warning(f"force guard: the wrench estimates lag {self.guard.estimate_lag:.3f} s behind "
                                      f"the states; this move runs at {guarded * 1e3:.2f} mm/s (speed_scale gives "
                                      f"{speed * 1e3:.2f}; guard_blind_travel_m {self.guard.estimates.blind_travel:g})")
            speed = guarded
        duration = minimum_jerk_duration(start_lengths, goal_lengths, speed, self.get_parameter(
            "trajectory_min_duration_s").value)
        period = self.get_parameter("trajectory_sample_period_s").value
        count = min(max(int(np.ceil(duration / period)), 2), MAX_TRAJECTORY_POINTS)  # long moves: fewer points
        times = np.linspace(duration / count, duration, count)
        pos, vel, acc = minimum_jerk(start_lengths, goal_lengths, duration, times)
        # what the six struts do together along the whole move, the emulator's own check of it
        check_strut_path(self.robot, lambda t: minimum_jerk(start_lengths, goal_lengths, duration, t)[0], 0.0,
                         duration, knots=times, start_pose=start_pose, what="the move")
        if self.tissue is not None:  # waypoint k: the trajectory's sample k (0 = the start, where the robot is)
            guesses = interpolate_poses(start_pose, goal_pose, count + 1)[1:]
            fk = forward_kinematics(self.robot, pos, guess=guesses)
            fk.raise_for_failure()
            check_path_forces(self.robot, fk.pose, self.tissue, first_index=1, count=count + 1)
        msg = JointTrajectory()
        msg.header.stamp.sec, msg.header.stamp.nanosec = 0, 0  # start now (joint_trajectory_controller rule)
        msg.joint_names = list(LEG_NAMES)
        for i, t in enumerate(times):
            point = JointTrajectoryPoint()
            point.positions = pos[i].tolist()
            point.velocities = vel[i].tolist()
            point.accelerations = acc[i].tolist()
            point.time_from_start = duration_msg(float(t))
            msg.points.append(point)
        return msg

    # -- plan_path service --------------------------------------------------
    def on_plan_path(self, request: PlanPath.Request, response: PlanPath.Response) -> PlanPath.Response:
        """A checked path through the request's waypoints (base; one waypoint: from the current pose estimate),
        straight in SE(3) between them (1 mm / 1 deg steps), every sample checked against the workspace, the
        strut limits and, with a tissue model, the strut forces; while the force guard is tripped a segment
        further in the stopped direction is refused. Nothing moves. A refusal carries its code, the failing
        waypoint (the end of the segment that fails) and the time along the path where it fails."""
        response.path = Path()
        response.path.header.frame_id = BASE_FRAME
        response.path.header.stamp = self.get_clock().now().to_msg()
        response.failing_waypoint, response.failing_time_s = -1, float("nan")
        try:
            poses, offset = self.plan_waypoints(request.waypoints)
            speed_scale = move_request(poses[-1], request.speed_scale, 0.0, 0.0, self.get_parameter(
                "speed_scale").value, 0.0, 0.0).speed_scale
            samples, duration = self.plan_segments(poses, offset, speed_scale, response)
        except StewartError as exc:
            reject(self, self.diagnostics, "plan_path request", f"{exc.outcome}: {exc}")
            response.outcome = outcome_of(exc)
            return response
        stamp = response.path.header.stamp
        response.path.poses = [pose_stamped(p, stamp) for p in samples]
        response.duration_s = duration
        response.outcome = outcome("SUCCEEDED", f"path of {len(samples)} samples through {len(poses)} waypoints "
                                   f"over {duration:.2f} s")
        self.diagnostics.set(OK, "path planned", last_path_waypoints=len(samples))
        return response

    def plan_waypoints(self, waypoints) -> tuple[list[np.ndarray], int]:
        """The waypoints' poses (6,) and how many were put before them (1: the current pose estimate, when the
        request has one waypoint)."""
        if not waypoints:
            raise InvalidInputError("plan_path needs at least one waypoint (one: from the current pose estimate)")
        poses = [base_pose(msg, f"plan_path waypoint {i}") for i, msg in enumerate(waypoints)]
        if len(poses) > 1:
            return poses, 0
        if self.pose is None:
            raise RefusedError("NOT_READY", "one waypoint and no pose estimate yet to start the path from")
        return [self.pose.copy()] + poses, 1

    def plan_segments(self, poses, offset: int, speed_scale: float, response) -> tuple[list, float]:
        """Every segment's checked samples and the path's duration (s: a minimum-jerk move per segment at
        ``speed_scale``); the failing waypoint and time go into ``response`` before the refusal is raised."""
        samples: list = []
        duration = 0.0
        speed = self.robot.limits.strut_velocity_max * speed_scale
        shortest = self.get_parameter("trajectory_min_duration_s").value
        for i in range(len(poses) - 1):
            try:
                self.guard.check_target(poses[i], poses[i + 1])
                segment = checked_path(self.robot, poses[i], poses[i + 1], tissue=self.tissue)
            except StewartError:
                response.failing_waypoint, response.failing_time_s = i + 1 - offset, duration
                raise
            lengths = check_pose(self.robot, np.array([poses[i], poses[i + 1]]))
            duration += minimum_jerk_duration(lengths[0], lengths[1], speed, shortest)
            samples.extend(segment if i == 0 else segment[1:])
        return samples, duration


def main(args=None) -> int:
    """Run the kinematics node until SIGINT / SIGTERM; returns the exit code (2: it cannot start)."""
    return run_node(KinematicsNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
