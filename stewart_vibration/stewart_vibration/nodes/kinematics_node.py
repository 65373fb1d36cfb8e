"""kinematics node: target poses -> checked minimum-jerk leg trajectories; leg states -> pose estimates;
a force guard over every move.

Topics (relative): sub platform/target_pose (PoseStamped), legs/joint_states
(JointState), platform/external_wrench_estimate (WrenchStamped, the guard's input);
pub legs/joint_trajectory (JointTrajectory, leg_* absolute lengths, m),
platform/pose_estimate (PoseStamped, FK of leg_i + vib_i, one per state with its stamp),
kinematics/guard_status (diagnostic_msgs/DiagnosticStatus, reliable + transient local: the force
guard armed or tripped, with its limits, the trip's figures and the peak load since).
Services: kinematics/plan_path (nav_msgs/GetPlan), kinematics/reset_guard (std_srvs/Trigger).
Diagnostics on /diagnostics, with the state stream's health (received, lost,
processed, lag); ERROR while the force guard is tripped. States arrive raw and are solved in vectorised
batches of ``batch_size`` (the emulator's bursts) or every ``batch_period_s`` (wall clock; FK
warm-started from the previous pose); wrench estimates likewise.

Targets (raw PoseStamped, so a frame_id with a NUL is seen whole): frame base or empty, finite, a unit
quaternion; one is refused while the move sent last is pending or under way and beyond ``target_rate_hz``
(motion.target_gate). Malformed messages on any input (states, targets, wrench estimates, /diagnostics)
are ignored, counted on /diagnostics (``malformed <input>``) and logged rate-limited (nodes.common.MalformedInputs).

Soft tissue: with ``tissue_config`` every target and plan_path request is also checked for the strut
forces it needs under that tissue model (motion.paths.check_path_forces: quasi-static Newton-Euler +
the tissue's elastic wrench), refused with the leg and the waypoint above strut_force_max_n.
Force guard (stewart_vibration.motion.force_guard): during a move the external-wrench estimate is watched
(subscribed for good; between moves only the newest of each batch is decoded); when the force
(moment) at the end of a stop commanded now would exceed ``guard_force_n`` (``guard_moment_nm``) the
struts are stopped smoothly along the planned path (a one-point trajectory within
guard_deceleration_scale x strut_acceleration_max), the node holds there, reports ERROR and refuses
targets further in that direction until kinematics/reset_guard or a new limit.
The guard is asked on every batch of estimates and of states (the states move the prediction on). A
move also stops (limit "estimates") when the newest wrench estimate is more than
``guard_max_estimate_age_s`` behind the newest joint state: the estimator is late, stalled or gone, the
guard blind. That is a pause: once the stop is over and estimates are fresh again, the node sends the same
target again, unless the load passed a limit meanwhile (then the trip is a latched force trip).
"""

from __future__ import annotations

import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped, WrenchStamped
from nav_msgs.msg import Path
from nav_msgs.srv import GetPlan
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from ..dynamics.tissue import load_tissue_option
from ..emulation.command_size import MAX_TRAJECTORY_POINTS
from ..emulation.vibration_status import STRUT_STOPS
from ..errors import InvalidInputError, MalformedMessageError, StewartError
from ..kinematics import check_pose, forward_kinematics
from ..kinematics.robot_config import load_robot
from ..kinematics.rotations import MESSAGE_QUATERNION_TOLERANCE, pose_to_position_quaternion
from ..kinematics.workspace import check_strut_path
from ..messages import cdr
from ..messages.stamped import MAX_JOINT_POSITION_M, pose_from_cdr, rows_within, wrenches_from_cdr
from ..messages.status_values import emulator_rejections, statuses_from_cdr, vibration_report_from_cdr
from ..messages.stream_health import StreamHealth
from ..motion.force_guard import BLIND_TRAVEL_M, MAX_ESTIMATE_AGE_S, RECEIPT_DELAY_S, ForceGuard, StopPlan
from ..motion.paths import check_path_forces, checked_path, interpolate_poses
from ..motion.profiles import minimum_jerk, minimum_jerk_duration
from ..motion.target_gate import TargetGate
from .common import (
    BASE_FRAME,
    ERROR,
    LEG_NAMES,
    OK,
    STREAM_DEPTH,
    WARN,
    Diagnostics,
    JointColumns,
    MalformedInputs,
    RawBatcher,
    check_frame,
    declare_float,
    duration_msg,
    duration_seconds,
    emulator_now,
    float_param,
    int_param,
    pose_from_msg,
    pose_stamped,
    reject,
    run_node,
    text_param,
)

STATUS_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
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
        self.declare_parameter("robot_config", "", text_param("robot YAML path ('' = config/robot.yaml)", True))
        self.declare_parameter(
            "trajectory_min_duration_s", 0.5, float_param("shortest point-to-point move, s", 0.05, 120.0)
        )
        self.declare_parameter(
            "trajectory_sample_period_s", 0.02, float_param("spacing of trajectory points, s", 0.001, 1.0)
        )
        self.declare_parameter(
            "speed_scale", 0.5, float_param("fraction of strut_velocity_max used by moves", 0.01, 1.0)
        )
        period = declare_float(self, "batch_period_s", 0.02, float_param(
            "queued states are solved at least this often (wall clock), s (read at start)", 0.001, 0.5,
            read_only=True))
        batch_size = self.declare_parameter("batch_size", 10, int_param(
            "states solved together as soon as this many have queued (read at start)", 1, 1000,
            read_only=True)).value
        self.declare_parameter("tissue_config", "", text_param(
            "soft-tissue YAML whose load targets and plan_path are checked against (strut_force_max_n; a name is "
            "looked up in config/; '' = none; read at start)", True))
        declare_float(self, "guard_force_n", 200.0, float_param(
            "force guard: a move is stopped before the estimated external force exceeds this, N (0 = off; example "
            "value, not a clinical limit; a change clears a trip)", 0.0, 5000.0))
        declare_float(self, "guard_moment_nm", 15.0, float_param(
            "force guard: likewise for the moment about the platform origin, N m (0 = off; example value; a change "
            "clears a trip)", 0.0, 500.0))
        declare_float(self, "guard_deceleration_scale", 0.8, float_param(
            "force guard: fraction of strut_acceleration_max a stop may use", 0.1, 1.0))
        declare_float(self, "guard_blind_travel_m", BLIND_TRAVEL_M, float_param(
            "force guard: moves are slowed so that the struts cover at most this in the time the external-wrench "
            "estimates lag behind the states (largest lag over the last 3 s), m (0 = never slowed)", 0.0, 0.05))
        declare_float(self, "guard_max_estimate_age_s", MAX_ESTIMATE_AGE_S, float_param(
            "force guard: a move pauses when the newest external-wrench estimate is this far behind the newest joint "
            "state, s (the guard would be blind; 0 = off)", 0.0, 5.0))
        target_rate = declare_float(self, "target_rate_hz", 5.0, float_param(
            "targets taken per second at most, in bursts of as many (wall clock; a target while a move is pending "
            "or under way is refused anyway; read at start)", 0.1, 100.0, read_only=True))
        path = self.get_parameter("robot_config").value
        self.robot = load_robot(path or None)
        self.tissue = load_tissue_option(self.get_parameter("tissue_config").value, self.robot)
        param = self.get_parameter
        self.guard = ForceGuard(self.robot, param("guard_force_n").value, param("guard_moment_nm").value,
                                param("guard_deceleration_scale").value, param("guard_max_estimate_age_s").value,
                                param("guard_blind_travel_m").value)
        self.batch_period = period
        self.state_time = None  # stamp of the newest joint state (the emulator's clock), s
        self.diagnostics = GuardedDiagnostics(self, "kinematics")
        self.diagnostics.guard = self.guard
        self.malformed = MalformedInputs(self, self.diagnostics)
        self.target_gate = TargetGate(self.guard, target_rate)
        self.lengths = None  # latest leg_* (strut) lengths, m
        self.pose = None  # latest pose estimate
        self.fk_failures = 0
        self.health = StreamHealth()
        self.columns = JointColumns()
        self.decoder = cdr.JointStateDecoder()
        self.pose_encoder = cdr.PoseStampedEncoder(BASE_FRAME)
        self.batcher = RawBatcher(self, batch_size, period, self.process)
        self.traj_pub = self.create_publisher(JointTrajectory, "legs/joint_trajectory", 10)
        self.pose_pub = self.create_publisher(PoseStamped, "platform/pose_estimate", STREAM_DEPTH)
        self.diagnostics.report_readers("platform/pose_estimate", self.pose_pub)
        # 1 s of states at 500 Hz: under CPU load the executor stalls > 0.1 s and depth 50 lost estimates
        self.create_subscription(JointState, "legs/joint_states", self.batcher.add, STREAM_DEPTH, raw=True)
        self.create_timer(1.0, self.report, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.diagnostics.watch("legs/joint_states", 1.0, "from hardware_emulator")
        # raw: rclpy's conversion cuts a string at a NUL, so a frame_id "base\0x" would read as "base"
        self.create_subscription(PoseStamped, "platform/target_pose", self.on_target_pose, 10, raw=True)
        self.create_service(GetPlan, "kinematics/plan_path", self.on_plan_path)
        self.wrench_decoder_errors = 0
        self.wrench_batcher = RawBatcher(self, batch_size, period, self.process_wrenches)
        # subscribed for good: a subscription made when a move starts is blind until DDS has matched it
        # (seconds on a busy machine: a guarded move once ran to its target unwatched)
        self.create_subscription(WrenchStamped, "platform/external_wrench_estimate", self.wrench_batcher.add,
                                 STREAM_DEPTH, raw=True)
        self.guard_pub = self.create_publisher(DiagnosticStatus, "kinematics/guard_status", STATUS_QOS)
        self.emulator_rejections = 0  # the hardware emulator's count of refused commands (its /diagnostics)
        self.stop_sent_at = None  # wall time of the last stop sent (a refusal after it means: stop again)
        self.last_target = None  # the target pose (6,) of the latest move sent (resumed after a blind stop)
        self.create_subscription(DiagnosticArray, "/diagnostics", self.on_diagnostics, 50, raw=True)
        # the emulator's own stops (e-stop, deactivate, shutdown, physics fault) end the move: never resumed
        self.create_subscription(DiagnosticStatus, "vibration/status", self.on_vibration_status, STATUS_QOS, raw=True)
        self.robot_stop_seen: tuple | None = None  # (ramp_start, ramp_reason, fault) of the last stop acted on
        self.create_service(Trigger, "kinematics/reset_guard", self.on_reset_guard)
        self.add_on_set_parameters_callback(self.on_set_parameters)
        self.publish_guard_status()
        self.diagnostics.set(OK, "waiting for legs/joint_states")
        self.get_logger().info(f"kinematics ready (robot {self.robot.source}, tissue "
                               f"{self.tissue.source if self.tissue else 'none'}; {self.guard.message()})")

    # -- state estimate ---------------------------------------------------
    def process(self, messages: list, arrivals: np.ndarray) -> None:
        """Solve FK for a batch of states (one batch per layout) and publish one estimate each."""
        self.diagnostics.seen("legs/joint_states")
        batches, kept = cdr.decode_joint_states_dropping_malformed(
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
        lengths = legs + (batch.position[:, vib_at] if vib_at is not None else 0.0)
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
        self.guard.observe_states(stamps, legs)
        # estimates already queued here are newer news than their absence: after a stall of this node the
        # states are taken first, and judging the guard blind before reading them would stop for nothing
        self.wrench_batcher.flush()
        now = self.emulator_now()
        # blind = estimates behind the states this node has read (not /clock: a stall of this node delays both)
        trip = self.guard.assess(now, self.batch_period) or self.guard.check_estimates(self.state_time)
        if trip is not None:
            self.on_trip(trip)
        retry = self.guard.missed_stop(now)
        if retry is not None:
            self.get_logger().error("force guard: the struts ran past the commanded stop still on the move (it did "
                                    f"not take); stopping again over {retry.duration:.2f} s")
            self.send_stop(retry)
        if self.diagnostics.message == "waiting for legs/joint_states":
            self.diagnostics.set(OK, "tracking")

    def report(self) -> None:
        self.diagnostics.values.update(self.health.values("states"))
        if self.health.behind:
            p99 = self.health.lag_percentiles_ms()[1]
            self.diagnostics.set(WARN, f"falling behind: {self.health.lost} states lost, lag p99 {p99:.1f} ms")
        self.diagnostics.publish()

    # -- force guard -------------------------------------------------------
    def process_wrenches(self, messages: list, arrivals: np.ndarray) -> None:
        """Wrench estimates: the guard's input (the newest only when it watches no move)."""
        if self.guard.move is None:
            messages = messages[-1:]
        batch = wrenches_from_cdr(messages, "external wrench estimate")
        for error in batch.errors:
            self.wrench_decoder_errors += 1
            self.malformed.refuse("platform/external_wrench_estimate", error)
        if not len(batch.kept):
            return
        stamps, wrenches = batch.stamps, batch.values
        was_watching = self.guard.move is not None
        trip = self.guard.observe(stamps, wrenches, self.emulator_now(stamps[-1]), self.batch_period)
        if trip is not None:
            self.on_trip(trip)
        elif self.guard.tripped and was_watching and self.guard.move is None:
            self.publish_guard_status()  # the stop is over: its peak load
        if self.state_time is not None and self.guard.blind_stop_over(self.state_time) and self.last_target is not None:
            if self.guard.resume_after_blind():
                self.get_logger().warning("force guard: external-wrench estimates are fresh again; resuming the "
                                          f"move to {np.round(self.last_target, 5).tolist()}")
                self.publish_guard_status()
                self.move_to(self.last_target)
            else:  # the load passed a limit while the guard could not see it: latched, held by the blind stop
                self.on_trip(self.guard.trip, send_stop=False)

    def emulator_now(self, fallback: float = 0.0) -> float:
        """The emulator's time as best known here (s): see nodes.common.emulator_now."""
        return emulator_now(self, self.state_time, fallback)

    def on_trip(self, trip, send_stop: bool = True) -> None:
        """Report a trip (ERROR, guard status) and send its stop (unless the struts are held already)."""
        if send_stop and trip.stop is not None:
            self.send_stop(trip.stop)
        message = self.guard.message()
        self.get_logger().error(f"force guard {message}")
        self.diagnostics.set(ERROR, f"force guard {message}")
        self.publish_guard_status()

    def on_diagnostics(self, data: bytes) -> None:
        """A refusal by the hardware emulator right after a stop was sent: stop again (over a wider window).
        Malformed statuses (and a malformed count in the emulator's) are counted and ignored."""
        statuses, errors = statuses_from_cdr(data)
        for error in errors:
            self.malformed.refuse("/diagnostics", error)
        for status in statuses:
            if status.node != "hardware_emulator":
                continue
            try:
                count = emulator_rejections(status)
            except MalformedMessageError as exc:
                self.malformed.refuse("/diagnostics", exc)
                continue
            if count is None or count <= self.emulator_rejections:
                continue
            self.emulator_rejections = count
            if self.stop_sent_at is not None and time.monotonic() - self.stop_sent_at < 5.0 and \
                    "rejected leg trajectory" in status.message:
                retry = self.guard.missed_stop(self.emulator_now(), refused=True)
                if retry is not None:
                    self.get_logger().error(f"force guard: the emulator refused the stop ({status.message}); "
                                            f"stopping again over {retry.duration:.2f} s")
                    self.send_stop(retry)

    def on_vibration_status(self, data: bytes) -> None:
        """The emulator's vibration/status (raw): a stop of the struts it made itself (STRUT_STOPS, or a latched
        physics fault) ends kinematics' move -- the guard drops it and the target is not resumed after a pause;
        a new target is needed once the robot is back (reset). A malformed status is counted and ignored."""
        report = self.malformed.read("vibration/status", vibration_report_from_cdr, data)
        if report is None:
            return
        stopped = report.fault or (report.ramp_start is not None and report.ramp_reason in STRUT_STOPS)
        key = (report.ramp_start, report.ramp_reason, report.fault)
        if not stopped or key == self.robot_stop_seen:
            return
        self.robot_stop_seen = key
        dropped = self.guard.robot_stopped()
        target, self.last_target = self.last_target, None
        if dropped or target is not None:
            why = f"physics fault: {report.fault}" if report.fault else report.ramp_reason
            self.get_logger().warning(f"the emulator stopped the robot ({why}): the move to "
                                      f"{None if target is None else np.round(target, 5).tolist()} is abandoned; "
                                      "send a new target once it is back")
            self.publish_guard_status()

    def send_stop(self, stop: StopPlan) -> None:
        """One-point leg trajectory (stamp 0 = now): the struts come to rest at ``stop.lengths``."""
        self.stop_sent_at = time.monotonic()
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
        guard = self.guard
        level = DiagnosticStatus.ERROR if guard.tripped else DiagnosticStatus.OK
        self.guard_pub.publish(DiagnosticStatus(
            level=level, name="kinematics: force guard", message=guard.message(), hardware_id="stewart_vibration",
            values=[KeyValue(key=k, value=v) for k, v in guard.status_values().items()]))

    def on_reset_guard(self, request, response):
        was = self.guard.reset()
        response.success = True
        response.message = "force guard reset: targets in every direction accepted again" if was else \
            "the force guard was not tripped (nothing to reset)"
        self.get_logger().info(response.message)
        self.diagnostics.set(OK, response.message)
        self.publish_guard_status()
        return response

    def on_set_parameters(self, params) -> SetParametersResult:
        """guard_* take effect at once; a changed limit clears a trip (the operator's decision)."""
        values = {p.name: float(p.value) for p in params if p.name in GUARD_PARAMS}
        if not values:
            return SetParametersResult(successful=True)
        if "guard_blind_travel_m" in values:
            self.guard.blind_travel = values["guard_blind_travel_m"]
        if "guard_max_estimate_age_s" in values:
            self.guard.max_estimate_age = values["guard_max_estimate_age_s"]
        if "guard_deceleration_scale" in values:
            self.guard.deceleration_scale = values["guard_deceleration_scale"]
        cleared = self.guard.set_limits(values.get("guard_force_n"), values.get("guard_moment_nm"))
        if cleared:
            self.get_logger().info("force guard: new limit, trip cleared")
            self.diagnostics.set(OK, "force guard: new limit, trip cleared")
        self.publish_guard_status()
        return SetParametersResult(successful=True)

    # -- target pose -> trajectory ----------------------------------------
    def on_target_pose(self, data: bytes) -> None:
        """A raw target PoseStamped: frame base (or empty), finite, a unit quaternion (within 1e-3), else refused
        (counted as malformed, WARN with the reason)."""
        try:
            _, target = pose_from_cdr(data, "target pose", MESSAGE_QUATERNION_TOLERANCE)
        except MalformedMessageError as exc:
            self.malformed.refuse("platform/target_pose", exc)
            reject(self, self.diagnostics, "target pose", str(exc), log=False)
            return
        self.move_to(target)

    def move_to(self, target: np.ndarray) -> None:
        """Plan and send the checked move to ``target`` (6,) (m, rad; base); refused with the reason when the
        pose or the path is infeasible, the guard blocks that direction, a move is pending or under way, or
        targets come faster than target_rate_hz."""
        try:
            goal_lengths = check_pose(self.robot, target)
        except StewartError as exc:
            reject(self, self.diagnostics, "target pose", str(exc))
            return
        if self.lengths is None or self.pose is None:
            reject(self, self.diagnostics, "target pose", "no legs/joint_states received yet")
            return
        try:
            self.guard.check_target(self.pose, target)
        except StewartError as exc:
            reject(self, self.diagnostics, "target pose", str(exc))
            return
        refusal = self.target_gate.refusal(self.emulator_now(), time.monotonic())
        if refusal is not None:
            reject(self, self.diagnostics, "target pose", refusal)
            return
        try:
            trajectory = self.plan_trajectory(self.lengths, self.pose, goal_lengths, target)
        except StewartError as exc:
            reject(self, self.diagnostics, "target pose", f"path not feasible: {exc}")
            return
        self.traj_pub.publish(trajectory)
        self.last_target = np.array(target, float)
        final = duration_seconds(trajectory.points[-1].time_from_start)
        start_time = self.emulator_now() + RECEIPT_DELAY_S
        self.guard.begin_move(start_time, final, self.lengths, goal_lengths, self.pose, target)
        if not np.isfinite(self.guard.newest_estimate) and (self.guard.force_limit > 0 or self.guard.moment_limit > 0):
            self.diagnostics.set(WARN, "trajectory sent UNGUARDED: no platform/external_wrench_estimate received yet "
                                 "(is leg_force_estimator running?)", last_target=np.round(target, 6).tolist(),
                                 last_duration_s=final)
            self.get_logger().warning("force guard: no external-wrench estimate received yet; this move is unguarded")
        else:
            self.diagnostics.set(OK, "trajectory sent", last_target=np.round(target, 6).tolist(),
                                 last_duration_s=final)
        self.get_logger().info(f"trajectory to {np.round(target, 5).tolist()} over {final:.3f} s")

    def plan_trajectory(self, start_lengths, start_pose, goal_lengths, goal_pose) -> JointTrajectory:
        """Minimum-jerk leg trajectory (at most MAX_TRAJECTORY_POINTS points), checked along the whole move for what
        the six struts do together (``kinematics.workspace.check_strut_path``: FK, joints, conditioning, the
        emulator's check too) and, with a tissue model, for the strut forces it needs (the waypoints are the
        trajectory's samples)."""
        speed = self.robot.limits.strut_velocity_max * self.get_parameter("speed_scale").value
        guarded = self.guard.speed_limit()  # slower while the wrench estimates lag (busy machine)
        if guarded < speed:
            self.get_logger().warning(f"force guard: the wrench estimates lag {self.guard.estimate_lag:.3f} s behind "
                                      f"the states; this move runs at {guarded * 1e3:.2f} mm/s (speed_scale gives "
                                      f"{speed * 1e3:.2f}; guard_blind_travel_m {self.guard.blind_travel:g})")
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
    def on_plan_path(self, request: GetPlan.Request, response: GetPlan.Response) -> GetPlan.Response:
        """Checked straight SE(3) path from start to goal (both in base). An unset start (empty frame_id,
        zero position, zero or identity orientation: what a goal-only request carries) means "from the
        current pose estimate". With a tissue model every waypoint's predicted strut forces are checked too;
        while the force guard is tripped a path further in the stopped direction is refused. An infeasible
        request gets an empty path; the reason goes to the log and /diagnostics (WARN, value
        last_plan_failure)."""
        response.plan = Path()
        response.plan.header.frame_id = BASE_FRAME
        response.plan.header.stamp = self.get_clock().now().to_msg()
        try:
            start_msg = request.start
            if unset_pose(start_msg):
                if self.pose is None:
                    raise InvalidInputError("start pose unset and no pose estimate yet")
                start = self.pose
            else:
                check_frame(start_msg.header.frame_id, "plan_path start")
                start = pose_from_msg(start_msg.pose)
            check_frame(request.goal.header.frame_id, "plan_path goal")
            goal = pose_from_msg(request.goal.pose)
            self.guard.check_target(start, goal)
            poses = checked_path(self.robot, start, goal, tissue=self.tissue)
        except StewartError as exc:
            reason = f"{type(exc).__name__}: {exc}"
            reject(self, self.diagnostics, "plan_path request (empty path returned)", reason)
            self.diagnostics.values["last_plan_failure"] = reason
            return response  # empty path = infeasible
        stamp = response.plan.header.stamp
        response.plan.poses = [pose_stamped(p, stamp) for p in poses]
        self.diagnostics.set(OK, "path planned", last_path_waypoints=len(poses))
        return response


def unset_pose(msg: PoseStamped) -> bool:
    """True for a PoseStamped left at its defaults (no frame, zero position, zero or identity orientation)."""
    p, q = msg.pose.position, msg.pose.orientation
    return msg.header.frame_id == "" and (p.x, p.y, p.z) == (0.0, 0.0, 0.0) and \
        (q.x, q.y, q.z) == (0.0, 0.0, 0.0) and q.w in (0.0, 1.0)


def main(args=None) -> int:
    """Run the kinematics node until SIGINT / SIGTERM; returns the exit code (2: it cannot start)."""
    return run_node(KinematicsNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
