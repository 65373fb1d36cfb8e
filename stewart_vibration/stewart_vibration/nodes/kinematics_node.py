"""kinematics node: leg states -> pose estimates; reduction moves (an action) -> checked minimum-jerk leg
trajectories; a force guard over every move.

Topics (relative): sub legs/joint_states (JointState), platform/external_wrench_estimate (WrenchStamped, the
guard's input), legs/trajectory_status (LegTrajectoryStatus: the robot's answer to each leg trajectory),
vibration/status; pub legs/joint_trajectory (JointTrajectory, leg_* absolute lengths, m),
platform/pose_estimate (PoseStamped, FK of leg_i + vib_i, one per state with its stamp; vib_i carried forward
by ``unit_sensor_latency_s``, estimation.sensed_lengths), kinematics/guard_status (ForceGuardStatus, reliable +
transient local: the guard armed or tripped, with its limits, the trip's figures and the peak load since).
Actions: kinematics/move_to_pose (MoveToPose, nodes.move_server: every move checked before it is sent, with
``tissue_config`` also for the strut forces under that tissue model), kinematics/calibrate (Calibrate, a
kinematic calibration run: nodes.calibration_server; reads platform/tracker_pose, publishes
kinematics/calibration_samples). Services: kinematics/plan_path (PlanPath: a checked path through waypoints,
under ``tissue_config`` likewise; nothing moves: motion.path_plan), kinematics/reset_guard (std_srvs/Trigger).
Diagnostics on /diagnostics, with the state stream's health (received, lost, processed, lag); ERROR while the
force guard is tripped. States arrive raw and are solved in vectorised batches of ``batch_size`` (the
emulator's bursts) or every ``batch_period_s`` (wall clock; kinematics.pose_tracking); wrench estimates
likewise. Malformed messages on the raw inputs (states, wrench estimates, vibration/status) are ignored,
counted on /diagnostics (``malformed <input>``) and logged rate-limited (nodes.diagnostics.MalformedInputs).

Force guard (motion.force_guard, driven by motion.guard_supervisor): during a move the wrench estimate is
watched (between moves only the newest of each batch is decoded); when the load at the end of a stop commanded
now would exceed ``guard_force_n`` / ``guard_moment_nm`` the struts are stopped smoothly along the path, held
there, ERROR is reported and goals further in that direction are refused (GUARD_BLOCKED) until
kinematics/reset_guard or a new limit. A move whose estimates lag the states by more than
``guard_max_estimate_age_s`` pauses and goes on once they are fresh, unless the load passed a limit meanwhile.
"""

from __future__ import annotations

import time

import numpy as np
from geometry_msgs.msg import PoseStamped, WrenchStamped
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from stewart_vibration_interfaces.msg import ForceGuardStatus, LegTrajectoryStatus, VibrationUnitsStatus
from stewart_vibration_interfaces.srv import PlanPath

from ..dynamics.tissue_config import load_tissue_option
from ..errors import MalformedMessageError, StewartError
from ..kinematics.pose_tracking import PoseTracker
from ..kinematics.robot_config import load_robot
from ..kinematics.rotations import pose_to_position_quaternion
from ..messages.fields import BASE_FRAME
from ..messages.joint_states import JointStateDecoder, decode_joint_states_dropping_malformed
from ..messages.leg_lengths import leg_lengths
from ..messages.stamped import wrenches_from_cdr
from ..messages.stamped_doubles import PoseStampedEncoder
from ..messages.stream_health import StreamHealth
from ..motion.force_guard import ForceGuard
from ..motion.goal_keeper import GoalKeeper
from ..motion.guard_parameters import apply_guard_parameters, guard_from_parameters
from ..motion.guard_supervisor import GuardSupervisor, PublishStatus, ResumeTarget, SendStop, Tripped
from ..motion.path_plan import path_waypoints, plan_path
from ..motion.strut_rest import StrutRest
from ..parameters.tables import KINEMATICS
from .calibration_server import CalibrationServer
from .diagnostics import ERROR, OK, WARN, Diagnostics, MalformedInputs, reject
from .message_conversions import JointColumns, RawBatcher, emulator_now
from .move_messages import base_pose, path_msg, path_refusal_msg
from .move_server import MoveServer
from .node_parameters import declare_table
from .run_loop import STATUS_QOS, STREAM_DEPTH, run_node
from .status_messages import guard_status_msg


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
    """States -> pose estimates (kinematics.pose_tracking), the guard's inputs and actions (motion.guard_supervisor),
    plan_path (motion.path_plan); the moves are nodes.move_server's, the calibration nodes.calibration_server's."""

    def __init__(self):
        super().__init__("kinematics")
        params = declare_table(self, KINEMATICS)
        period, batch_size = params["batch_period_s"], params["batch_size"]
        self.robot = load_robot(params["robot_config"] or None)
        self.tissue = load_tissue_option(params["tissue_config"], self.robot)
        self.guard = guard_from_parameters(self.robot, params)
        self.supervisor = GuardSupervisor(self.guard, period)
        self.goals = GoalKeeper(self.robot, self.supervisor)
        self.tracker = PoseTracker(self.robot)
        self.unit_latency = float(params["unit_sensor_latency_s"])
        self.state_time = None  # stamp of the newest joint state (the emulator's clock), s
        self.lengths = None  # latest leg_* (strut) lengths, m
        self.rest = StrutRest()
        self.diagnostics = GuardedDiagnostics(self, "kinematics")
        self.diagnostics.guard = self.guard
        self.malformed = MalformedInputs(self, self.diagnostics)
        self.health, self.columns, self.decoder = StreamHealth(), JointColumns(), JointStateDecoder()
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
        self.wrench_batcher = RawBatcher(self, batch_size, period, self.process_wrenches)
        # subscribed for good: a subscription made when a move starts is blind until DDS has matched it
        # (seconds on a busy machine: a guarded move once ran to its target unwatched)
        self.create_subscription(WrenchStamped, "platform/external_wrench_estimate", self.wrench_batcher.add,
                                 STREAM_DEPTH, raw=True)
        self.guard_pub = self.create_publisher(ForceGuardStatus, "kinematics/guard_status", STATUS_QOS)
        self.moves = MoveServer(self, params["target_rate_hz"])
        self.create_subscription(LegTrajectoryStatus, "legs/trajectory_status", self.moves.on_trajectory_status, 50)
        # the emulator's own stops (e-stop, deactivate, shutdown, physics fault) end the move: never resumed
        self.create_subscription(VibrationUnitsStatus, "vibration/status", self.moves.on_vibration_status,
                                 STATUS_QOS, raw=True)
        self.create_service(Trigger, "kinematics/reset_guard", self.on_reset_guard)
        self.calibration = CalibrationServer(self)
        self.add_post_set_parameters_callback(self.on_parameters_set)
        self.publish_guard_status()
        self.diagnostics.set(OK, "waiting for legs/joint_states")
        self.waiting_for_states = True  # until the first state: then "tracking", unless a warning was set meanwhile
        self.get_logger().info(f"kinematics ready (robot {self.robot.source}, tissue "
                               f"{self.tissue.source if self.tissue else 'none'}; {self.guard.message()})")

    @property
    def pose(self) -> np.ndarray | None:
        """The newest pose estimate (6,) (m, rad; base), None before any."""
        return self.tracker.pose

    def param(self, name: str):
        return self.get_parameter(name).value

    def emulator_now(self, fallback: float = 0.0) -> float:
        """The emulator's time as best known here (s): see nodes.message_conversions.emulator_now."""
        return emulator_now(self, self.state_time, fallback)

    # -- state estimate ---------------------------------------------------
    def process(self, messages: list, arrivals: np.ndarray) -> None:
        """Solve FK for a batch of states (one batch per layout) and publish one estimate each."""
        self.diagnostics.seen("legs/joint_states")
        batches, kept = decode_joint_states_dropping_malformed(
            messages, self.decoder, lambda reason: self._malformed(MalformedMessageError(reason)))
        arrivals = arrivals[kept]
        first = 0
        for batch in batches:
            self._solve(batch, arrivals[first:first + len(batch.stamps)])
            first += len(batch.stamps)

    def _malformed(self, error: MalformedMessageError, count: int = 1) -> None:
        self.malformed.refuse("legs/joint_states", error, count)
        self.health.rejected += count

    def _solve(self, batch, arrivals) -> None:
        self.health.arrived(batch.stamps)
        legs_at, vib_at = self.columns(batch.names)
        states = leg_lengths(batch, legs_at, vib_at, self.unit_latency)
        for error, count in states.dropped:
            self._malformed(error, count)
        if not len(states.stamps):
            return
        try:
            solved = self.tracker.solve(states.lengths)
        except StewartError as exc:
            self._malformed(MalformedMessageError(f"joint state: {exc}", field="position", kind="range"),
                            len(states.stamps))
            return
        ok, stamps, legs = solved.ok, states.stamps, states.struts
        if not ok.all():
            self.diagnostics.set(WARN, "forward kinematics did not converge", fk_failures=self.tracker.failures)
            if not ok.any():
                return
        position, quaternion = pose_to_position_quaternion(solved.poses)
        for stamp, p, q in zip(stamps[ok], position, quaternion, strict=True):
            self.pose_pub.publish(self.pose_encoder.encode(stamp, p, q))
        self.health.done(arrivals[states.kept][ok], time.monotonic())
        self.lengths, self.state_time = legs[ok][-1], float(stamps[-1])
        self.rest.observe(stamps[ok], legs[ok])
        self.moves.settle_rest_wait()
        self.calibration.on_states(stamps[ok], states.lengths[ok], batch.effort[states.kept][:, legs_at][ok])
        self.supervisor.states_read(stamps, legs)
        # estimates already queued here are newer news than their absence: after a stall of this node the
        # states are taken first, and judging the guard blind before reading them would stop for nothing
        self.wrench_batcher.flush()
        self.carry_out(self.supervisor.on_states(self.emulator_now(), self.state_time))
        if self.waiting_for_states:
            self.waiting_for_states = False
            if self.diagnostics.level == OK:
                self.diagnostics.set(OK, "tracking")
        self.moves.follow()

    def report(self) -> None:
        self.diagnostics.values.update(self.health.values("states"))
        if self.health.behind:
            p99 = self.health.lag_percentiles_ms()[1]
            self.diagnostics.set(WARN, f"falling behind: {self.health.lost} states lost, lag p99 {p99:.1f} ms")
        self.diagnostics.publish()

    # -- force guard -------------------------------------------------------
    def process_wrenches(self, messages: list, arrivals: np.ndarray) -> None:
        """Wrench estimates: the guard's input (the newest only when it watches no move)."""
        if self.guard.move is None and self.goals.goal is None:
            messages = messages[-1:]
        batch = wrenches_from_cdr(messages, "external wrench estimate")
        for error in batch.errors:
            self.malformed.refuse("platform/external_wrench_estimate", error)
        if not len(batch.kept):
            return
        self.goals.observe_load(batch.values)
        self.carry_out(self.supervisor.on_wrenches(batch.stamps, batch.values, self.emulator_now(batch.stamps[-1]),
                                                   self.state_time, self.goals.last_target is not None))

    def carry_out(self, actions: list) -> None:
        """Do what the guard's supervisor (or the goal keeper) decided: send stops, report trips, publish the
        guard's status, resume."""
        for action in actions:
            if isinstance(action, SendStop):
                if action.why:
                    self.get_logger().error(f"{action.why}; stopping again over {action.stop.duration:.2f} s")
                self.moves.send_stop(action.stop, action.by, action.attempt)
            elif isinstance(action, Tripped):
                self.on_trip(action.trip, held=action.held)
            elif isinstance(action, PublishStatus):
                self.publish_guard_status()
            elif isinstance(action, ResumeTarget):
                self.moves.resume()

    def on_trip(self, trip, held: bool = False) -> None:
        message = f"force guard {self.guard.message()}"
        self.goals.tripped(trip, held, self.emulator_now(), message)
        self.get_logger().error(message)
        self.diagnostics.set(ERROR, message)
        self.publish_guard_status()

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
        """After a set (checked by the table): guard_* take effect at once; a changed limit clears a trip."""
        cleared = apply_guard_parameters(self.guard, {p.name: p.value for p in params})
        if cleared is None:
            return
        if cleared:
            self.get_logger().info("force guard: new limit, trip cleared")
            self.diagnostics.set(OK, "force guard: new limit, trip cleared")
        self.publish_guard_status()

    def shutdown(self) -> None:
        """A goal still running ends SHUTDOWN, and so does a calibration (the robot finishes or holds what it was
        sent)."""
        self.moves.shutdown()
        self.calibration.shutdown()

    # -- plan_path service --------------------------------------------------
    def on_plan_path(self, request: PlanPath.Request, response: PlanPath.Response) -> PlanPath.Response:
        """A checked path through the request's waypoints (one: from the current pose estimate); nothing moves."""
        stamp = self.get_clock().now().to_msg()
        try:
            poses, offset = path_waypoints([base_pose(msg, f"plan_path waypoint {i}")
                                            for i, msg in enumerate(request.waypoints)], self.pose)
            plan = plan_path(self.robot, poses, offset, request.speed_scale, self.param("speed_scale"),
                             self.param("trajectory_min_duration_s"), self.guard, self.tissue)
        except StewartError as exc:
            reject(self, self.diagnostics, "plan_path request", f"{exc.outcome}: {exc}")
            return path_refusal_msg(response, exc, stamp)
        self.diagnostics.set(OK, "path planned", last_path_waypoints=len(plan.samples))
        return path_msg(response, plan, len(poses), stamp)


def main(args=None) -> int:
    """Run the kinematics node until SIGINT / SIGTERM; returns the exit code (2: it cannot start)."""
    return run_node(KinematicsNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
