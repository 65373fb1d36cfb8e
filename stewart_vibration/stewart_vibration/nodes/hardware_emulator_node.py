"""hardware_emulator node: the robot in MuJoCo, owning /clock (sim time).

Topics (relative): sub legs/joint_trajectory (leg_*, absolute strut lengths),
vibration/joint_trajectory (vib_*, header stamp = common start time); pub
legs/joint_states (leg_*, vib_*: position m, velocity m/s, effort = axial
force N: the sensors -- encoders, unit sensors, load cells), platform/imu (sensor_msgs/Imu in
`platform`, one per state: specific force and rates, see emulation.platform_sensors), platform/tracker_pose
(PoseStamped in `base`, the optical tracker's frames, stamped at capture), the truth for judging runs
(no controller reads it): ground_truth/joint_states (as legs/joint_states, true strut lengths, unit
displacements and axial forces), ground_truth/platform_pose (PoseStamped in `base`),
vibration/status (stewart_vibration_interfaces/VibrationUnitsStatus, reliable + transient local:
what the vibration units really do, see emulation.vibration_status), legs/trajectory_status
(LegTrajectoryStatus: the answer to each leg trajectory),
robot_markers (visualization_msgs/MarkerArray), /clock, /diagnostics; with a
``tissue_config`` also ground_truth/tissue_wrench (WrenchStamped in `base`, one per
state: the soft-tissue wrench the emulator applies from that instant, force N
and moment N m about the platform origin -- the convention of
platform/external_wrench_estimate).
Services: hardware_emulator/reset, hardware_emulator/emergency_stop (Trigger).

Physics runs in its own thread (emulation.physics_thread), one block of steps per state period, paced by
``real_time_factor`` (0 = as fast as possible; emulation.wall_pace); above real time (or at any rate with
``lockstep``) it also waits for the nodes' estimates (``max_consumer_lag_s``, see emulation.consumer_pace);
commands arrive on the executor thread and are handed over under a lock. The 500 Hz streams are published as
serialized CDR (messages.cdr), the commands are decoded from raw bytes.
"""

from __future__ import annotations

import functools
import math
import threading
import traceback
from typing import cast

import mujoco
from geometry_msgs.msg import PoseStamped, WrenchStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock as RosClock
from rclpy.clock import ClockType
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import MarkerArray

from stewart_vibration_interfaces.msg import LegTrajectoryStatus, VibrationUnitsStatus

from ..dynamics.tissue_config import load_tissue_option
from ..emulation.command_intake import (
    LegTrajectoryAnswers,
    lifecycle_refusal,
    refuse_unread,
    take_leg_trajectory,
    take_vibration_window,
)
from ..emulation.command_size import LEG_TRAJECTORY, VIBRATION_WINDOW
from ..emulation.consumer_pace import ConsumerPace, paces_consumers
from ..emulation.emulator import HardwareEmulator
from ..emulation.emulator_reports import RejectionTally, StatusRepeats, latched_first, thinned
from ..emulation.physics_thread import Block, BlockFailure, BlockSchedule, PhysicsThread
from ..emulation.plant import load_plant_option
from ..emulation.vibration_status import DEACTIVATED, SHUTDOWN
from ..emulation.wall_pace import WallPace
from ..errors import StewartError
from ..kinematics.robot_config import load_drawing
from ..messages import cdr, joint_states, joint_trajectory, stamped_doubles
from ..messages.fields import BASE_FRAME, PLATFORM_FRAME
from ..parameters.tables import HARDWARE_EMULATOR
from ..robot import LEG_NAMES, VIB_NAMES
from ..sim.mjcf import load_simulation_settings
from ..visualization.robot_outline import robot_outline
from .diagnostics import ERROR, OK, WARN, Diagnostics, MalformedInputs
from .emulator_messages import leg_trajectory_status_msg, robot_markers_msg
from .node_parameters import declare_table
from .run_loop import STATUS_QOS, STREAM_DEPTH, run_node
from .status_messages import vibration_status_msg

CLOCK_DEPTH = 100
AT_CONFIGURE = frozenset(spec.name for spec in HARDWARE_EMULATOR if spec.at_configure)
STATUS_PERIOD_S = 0.1  # sim time between vibration status evaluations (events are published at once)
STATUS_REPEAT_S = 1.0  # wall time between repeats of an unchanged status
# what the emulator waits for above real time: the force guard's input and kinematics' own output (one per state)
PACED_BY = {"platform/external_wrench_estimate": WrenchStamped, "platform/pose_estimate": PoseStamped}
STOP_WAIT_S = 3.0  # wall time the emulator waits at shutdown for the robot to brake to rest (the bring-up's grace: 5 s)


class HardwareEmulatorNode(LifecycleNode):
    """Thin adapter over stewart_vibration.emulation.HardwareEmulator, as a managed (lifecycle) node -- the
    interface a real hardware driver replaces it with:

    - configure: read the robot and simulation configs and the parameters read at configure (settable while
      unconfigured, refused with the reason while configured), build the model (a bad config fails the
      transition with the reason); create the publishers. Sim time goes on from where the last robot of this
      node left it: /clock never goes back within a run.
    - activate: start the physics thread (and /clock); commands are accepted.
    - deactivate: the robot is brought to a safe stop -- the vibration ramps out and the struts brake to rest
      along their commanded path within their acceleration limit, physics and /clock go on -- and commands are
      refused with the reason.
    - cleanup / shutdown: brake to rest (bounded, STOP_WAIT_S), stop physics and release the model.

    Physics never dies: a divergence (``emulation.physics_guard``) or an exception in the physics thread
    latches a fault, the robot is held at its last good state, /diagnostics and vibration/status report
    ERROR, and the held state and /clock go on being published; cleanup + configure build a new robot.

    ``autostart`` (default true) configures and activates at start, so ``ros2 run`` gives a running robot;
    the bring-up and the launch file set it false and drive the transitions themselves.
    """

    def __init__(self):
        super().__init__("hardware_emulator")
        declare_table(self, HARDWARE_EMULATOR)
        self.add_on_set_parameters_callback(self.refuse_configure_parameters_while_configured)
        self.run_clock = 0.0  # sim time (s) a robot built again at configure starts from: the run's clock goes on
        self.wall_pace = WallPace(self.get_parameter("real_time_factor").value)
        self.consumers = ConsumerPace(self.get_parameter("max_consumer_lag_s").value)
        self.lockstep = bool(self.get_parameter("lockstep").value)
        self.pace_subs: list = []
        self.lock = threading.Lock()
        self.emulator: HardwareEmulator | None = None
        self.physics: PhysicsThread | None = None  # exists while configured
        self.active = False
        self.mujoco_warnings = 0
        # MuJoCo's warnings go to this node's log (not stderr and MUJOCO_LOG.TXT in the working directory); the
        # physics guard sees them in MuJoCo's counters either way
        mujoco.set_mju_user_warning(self._mujoco_warning)
        self.status_repeats = StatusRepeats(STATUS_REPEAT_S)
        self.diagnostics = Diagnostics(self, "hardware emulator")
        self.diagnostics.set(WARN, "unconfigured (lifecycle: configure, then activate)")
        self.rejections = RejectionTally()
        self.malformed = MalformedInputs(self, self.diagnostics)  # e.g. a /clock that is no time (run_node)
        self.state_encoder = joint_states.JointStateEncoder(LEG_NAMES + VIB_NAMES)
        self.pose_encoder = stamped_doubles.PoseStampedEncoder(BASE_FRAME)
        self.wrench_encoder = stamped_doubles.WrenchStampedEncoder(BASE_FRAME)
        self.imu_encoder = stamped_doubles.ImuEncoder(PLATFORM_FRAME)
        self.tissue_pub = None
        self.create_subscription(JointTrajectory, "legs/joint_trajectory", self.on_leg_trajectory, 10, raw=True)
        self.leg_answers = LegTrajectoryAnswers()
        self.trajectory_status_pub = self.create_publisher(LegTrajectoryStatus, "legs/trajectory_status", 50)
        self.create_subscription(JointTrajectory, "vibration/joint_trajectory", self.on_vibration, 50, raw=True)
        self.create_service(Trigger, "hardware_emulator/reset", self.on_reset)
        self.create_service(Trigger, "hardware_emulator/emergency_stop", self.on_emergency_stop)
        self.add_post_set_parameters_callback(self.on_parameters_set)
        self.create_timer(STATUS_REPEAT_S, self.repeat_status, clock=RosClock(clock_type=ClockType.STEADY_TIME))
        if self.get_parameter("autostart").value:
            if self.trigger_configure() != TransitionCallbackReturn.SUCCESS:
                raise RuntimeError("configure failed (see the log)")
            self.trigger_activate()

    # -- lifecycle ------------------------------------------------------------------------
    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        param = self.get_parameter
        try:
            # the robot as drawn: a calibrated file is the controller's model of this robot, not the robot
            robot = load_drawing(param("robot_config").value or None)
            settings = load_simulation_settings(param("simulation_config").value or None,
                                                timestep=1.0 / param("physics_rate_hz").value)
            tissue = load_tissue_option(param("tissue_config").value, robot)
            seed = int(param("plant_seed").value)
            plant = load_plant_option(param("plant_config").value, robot, seed if seed >= 0 else None)
            emulator = HardwareEmulator(robot, settings, param("watchdog_s").value, param("vibration_ramp_s").value,
                                        param("drive_gain_interval").value, param("max_lookahead_s").value,
                                        tissue=tissue, plant=plant, sensor_rate_hz=param("state_rate_hz").value,
                                        start_time=self.run_clock)
        except (StewartError, ValueError, OSError) as exc:
            self.get_logger().error(f"configure failed: {type(exc).__name__}: {exc}")
            self.diagnostics.set(ERROR, f"configure failed: {exc}")
            return TransitionCallbackReturn.FAILURE
        schedule = BlockSchedule.from_rates(param("state_rate_hz").value, param("clock_rate_hz").value,
                                            param("marker_rate_hz").value, STATUS_PERIOD_S,
                                            param("pace_period_s").value)
        with self.lock:
            self.emulator = emulator
            self.physics = PhysicsThread(emulator, self.lock, schedule, self.wall_pace, self.consumers,
                                         paced_by_consumers=lambda: bool(self.pace_subs))
        self.state_pub = self.create_publisher(JointState, "legs/joint_states", STREAM_DEPTH)
        self.imu_pub = self.create_publisher(Imu, "platform/imu", STREAM_DEPTH)
        self.tracker_pub = self.create_publisher(PoseStamped, "platform/tracker_pose", 10)
        # the truth, for judging runs (recorder, run summary, tests); no controller reads these
        self.true_state_pub = self.create_publisher(JointState, "ground_truth/joint_states", STREAM_DEPTH)
        self.pose_pub = self.create_publisher(PoseStamped, "ground_truth/platform_pose", STREAM_DEPTH)
        # 1 s of ticks: the ticks of a 20 ms pace period leave in one burst, and a reader (the recorder) that
        # stalls longer than the history loses them
        self.clock_pub = self.create_publisher(Clock, "/clock", CLOCK_DEPTH)
        self.marker_pub = self.create_publisher(MarkerArray, "robot_markers", 5)
        self.status_pub = self.create_publisher(VibrationUnitsStatus, "vibration/status", STATUS_QOS)
        self.tissue_pub = None
        if tissue is not None:
            self.tissue_pub = self.create_publisher(WrenchStamped, "ground_truth/tissue_wrench", STREAM_DEPTH)
        self._update_pacing()
        self.diagnostics.set(OK, "configured (inactive: commands are refused until activate)",
                             physics_rate_hz=param("physics_rate_hz").value,
                             servo_bandwidth_hz=settings.servo_bandwidth_hz,
                             tissue=tissue.source if tissue is not None else "none",
                             plant=f"{plant.kind} (seed {plant.seed})" if plant is not None else "ideal")
        built = f"{plant.kind} seed {plant.seed} ({plant.source})" if plant is not None else "ideal"
        self.get_logger().info(f"configured: MuJoCo dt {emulator.dt} s, {settings.emulator_integrator}, "
                               f"robot {robot.source}, tissue "
                               f"{f'{tissue.name} ({tissue.source})' if tissue is not None else 'none'}, plant {built}")
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        physics = cast(PhysicsThread, self.physics)  # activate comes only from configured
        if not physics.running:
            physics.start(self.physics_loop)
        self.active = True
        self.publish_status(cast(HardwareEmulator, self.emulator).status.report)  # says at once it takes commands
        self.diagnostics.set(OK, "running")
        self.get_logger().info("active: physics running, commands accepted")
        return super().on_activate(state)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        with self.lock:  # the emulator exists: deactivate comes only from active (configured)
            self.active = False
            cast(HardwareEmulator, self.emulator).halt(DEACTIVATED)
            report = cast(HardwareEmulator, self.emulator).status.report
        self.publish_status(report)  # says at once it refuses commands
        self.diagnostics.set(self._level(WARN), self._message(
            "inactive: robot stopped safely (vibration ramped out, struts braked to rest within their acceleration "
            "limit, then held); commands refused"))
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._stop_physics(SHUTDOWN)
        self._update_pacing(False)
        for pub in (self.state_pub, self.imu_pub, self.tracker_pub, self.true_state_pub, self.pose_pub,
                    self.clock_pub, self.marker_pub, self.status_pub, self.tissue_pub):
            if pub is not None:
                self.destroy_publisher(pub)
        with self.lock:
            self.run_clock = cast(HardwareEmulator, self.emulator).time
            self.emulator, self.physics = None, None
        self.diagnostics.set(WARN, "unconfigured (cleaned up; a configure goes on from the run's clock)")
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._stop_physics(SHUTDOWN)
        return TransitionCallbackReturn.SUCCESS

    def _stop_physics(self, reason: str) -> None:
        """Brake the robot to rest (a safety stop, bounded: STOP_WAIT_S of wall time), then stop physics and
        refuse commands."""
        physics = self.physics
        if physics is not None and not physics.brake_to_rest(reason, STOP_WAIT_S):
            self.get_logger().warning(f"{reason}: the robot was still braking after {STOP_WAIT_S:g} s; physics "
                                      "stops anyway")
        self.active = False
        if physics is not None:
            physics.stop()

    def _refusal(self) -> str | None:
        """Why commands cannot be taken now, or None."""
        return lifecycle_refusal(self.emulator is not None, self.active)

    # -- parameters -------------------------------------------------------------------
    def refuse_configure_parameters_while_configured(self, params) -> SetParametersResult:
        """A parameter read at configure is set while the node is unconfigured (applied at the next configure);
        while it is configured the set is refused, saying how."""
        late = [p.name for p in params if p.name in AT_CONFIGURE]
        if late and self.emulator is not None:
            return SetParametersResult(successful=False, reason=(
                f"{', '.join(late)}: read at configure and the emulator is configured; deactivate and clean it up "
                f"(ros2 lifecycle set {self.get_fully_qualified_name()} cleanup), set it, then configure again"))
        return SetParametersResult(successful=True)

    def on_parameters_set(self, params) -> None:
        """After a set (validated by the table's check; read-only ones refused by rclpy with the reason): live
        parameters take effect at once."""
        with self.lock:
            for p in params:
                if p.name == "max_consumer_lag_s":  # held by the node, not the emulator: also before configure
                    self.consumers.max_lag_s = float(p.value)
                    continue
                if p.name == "lockstep":
                    self.lockstep = bool(p.value)
                    self.wall_pace.restart()
                    self._update_pacing()
                    continue
                if self.emulator is None and p.name != "real_time_factor":
                    continue  # read again at configure
                if p.name == "real_time_factor":
                    self.wall_pace.real_time_factor = float(p.value)
                    self.wall_pace.restart()
                    self._update_pacing()
                elif p.name == "watchdog_s":  # here and below the emulator exists (see the continue above)
                    cast(HardwareEmulator, self.emulator).vibration.watchdog_s = float(p.value)
                elif p.name == "vibration_ramp_s":
                    cast(HardwareEmulator, self.emulator).vibration.ramp_s = float(p.value)
                elif p.name == "max_lookahead_s":
                    cast(HardwareEmulator, self.emulator).vibration.max_lookahead_s = float(p.value)

    def _update_pacing(self, wanted: bool | None = None) -> None:
        """Subscribe to the consumers' outputs while physics paces itself by them (above real time, or in
        lockstep), unsubscribe otherwise: at 1x the 500 Hz streams would cost CPU for nothing."""
        if wanted is None:
            wanted = self.emulator is not None and paces_consumers(self.wall_pace.real_time_factor, self.lockstep)
        if wanted and not self.pace_subs:
            self.pace_subs = [self.create_subscription(msg_type, topic, functools.partial(self._heard, topic),
                                                       STREAM_DEPTH, raw=True) for topic, msg_type in PACED_BY.items()]
        elif not wanted and self.pace_subs:
            for sub in self.pace_subs:
                self.destroy_subscription(sub)
            self.pace_subs = []
            self.consumers.forget()

    def _heard(self, topic: str, data: bytes) -> None:
        stamp = cdr.header_stamp_ns(data)
        if stamp is not None:
            self.consumers.heard(topic, stamp * 1e-9)

    # -- commands (executor thread) ------------------------------------------------------
    def on_leg_trajectory(self, data: bytes) -> None:
        """A leg trajectory: taken or refused; the typed answer goes to legs/trajectory_status either way."""
        traj, error, end_time = None, None, math.nan
        try:
            refuse_unread(self._refusal(), data, LEG_TRAJECTORY)
            traj = joint_trajectory.decode_joint_trajectory(data)
            end_time = take_leg_trajectory(cast(HardwareEmulator, self.emulator), traj, self.lock)  # not refused
        except StewartError as exc:
            error = exc
            self.reject("leg trajectory", str(exc))
        answer = self.leg_answers.answer(traj, error, end_time, self.emulator.time if self.emulator else 0.0)
        self.trajectory_status_pub.publish(leg_trajectory_status_msg(answer))
        if error is None:
            self.diagnostics.set(self._level(OK), self._message("following leg trajectory"),
                                 last_leg_trajectory_points=answer.points)

    def on_vibration(self, data: bytes) -> None:
        try:
            refuse_unread(self._refusal(), data, VIBRATION_WINDOW)
            traj = joint_trajectory.decode_joint_trajectory(data)
        except StewartError as exc:
            self.reject("vibration command", str(exc))
            return
        report, error = take_vibration_window(cast(HardwareEmulator, self.emulator), traj, self.lock)
        if error is not None:
            self.reject("vibration command", str(error))
        self.publish_status(report)

    def on_emergency_stop(self, request, response):
        if self.emulator is None:
            response.success, response.message = False, self._refusal()
            return response
        with self.lock:
            self.emulator.emergency_stop()
            report = self.emulator.vibration_report()[0]
        self.publish_status(report)
        self.get_logger().warning("emergency stop: vibration ramping to zero, struts braking to rest (within "
                                  "their acceleration limit), then held")
        self.diagnostics.set(ERROR, "emergency stop latched (call hardware_emulator/reset to clear)")
        response.success, response.message = True, ("vibration ramping to zero, struts braking to rest and held; "
                                                     "reset to clear")
        return response

    def on_reset(self, request, response):
        refusal = self._refusal()
        if refusal:
            response.success, response.message = False, refusal
            return response
        try:
            with self.lock:
                duration = self.emulator.reset()
                report = self.emulator.vibration_report()[0]
        except StewartError as exc:
            response.success, response.message = False, str(exc)
            self.reject("reset", str(exc))
            return response
        self.publish_status(report)
        self.diagnostics.set(OK, "reset: e-stop cleared, returning home")
        response.success = True
        response.message = f"e-stop cleared; returning home over {duration:.2f} s (sim time)"
        return response

    def reject(self, what: str, reason: str) -> None:
        """A refused command: counted and on /diagnostics (WARN, never below an e-stop's ERROR), logged thinned."""
        if self.rejections.add(what, reason):
            self.get_logger().warning(f"rejected {what}: {reason} ({self.rejections.count} rejections so far)")
        self.diagnostics.set(self._level(WARN), self._message(f"rejected {what}: {reason}"),
                             last_rejection=reason, rejections=self.rejections.count)

    def _level(self, level):
        """Never report better than ERROR while the e-stop or a physics fault is latched."""
        return ERROR if self.emulator is not None and self.emulator.estopped else level

    def _message(self, message: str) -> str:
        """A latched physics fault or e-stop stays first in the diagnostics message."""
        if self.emulator is None:
            return message
        return latched_first(message, self.emulator.fault, self.emulator.estopped)

    # -- vibration status -------------------------------------------------------------------
    def publish_status(self, report) -> None:
        self.status_pub.publish(vibration_status_msg(report, self.active))
        self.status_repeats.sent(report.event_seq)

    def repeat_status(self) -> None:
        """Republish an unchanged status once a second (its amplitudes and times move on)."""
        if self.emulator is None:
            return
        if self.status_repeats.repeat_due():
            with self.lock:
                report = self.emulator.status.report
            self.publish_status(report)

    # -- physics outputs (physics thread) ---------------------------------------------------
    def physics_loop(self) -> None:
        """The physics thread: never dies on an exception in a block (``PhysicsThread.run``); a failure it cannot
        recover from is logged and reported."""
        physics = cast(PhysicsThread, self.physics)  # started only while configured
        try:
            physics.run(self)
        except Exception as exc:  # noqa: BLE001 - last resort: report, the robot is held where it was
            physics.running = False
            text = f"physics stopped: {type(exc).__name__}: {exc}"
            self.get_logger().error(f"{text}\n{traceback.format_exc()}")
            self.diagnostics.set(ERROR, f"{text}; the robot is held where it was (restart the emulator)")

    def publish_block(self, block: Block) -> None:
        """One state period out: /clock when due, the sensors and the truth, a newly latched physics fault
        (/diagnostics, the log), the vibration status when it has news, the markers when due."""
        self.publish_state(block.sensors, block.truth, block.time, clock=block.clock_due)
        fault = block.new_fault
        if fault is not None:
            self.get_logger().error(f"physics fault at sim time {fault.time:.3f} s: {fault.reason}; the robot is held "
                                    "at its last good state (cleanup + configure to rebuild)")
            self.diagnostics.set(ERROR, self._message("physics stopped following the commands"),
                                 physics_fault=fault.reason, physics_fault_time_s=f"{fault.time:.6f}",
                                 physics_errors=cast(PhysicsThread, self.physics).failures)
        report = block.report
        if report is not None and self.status_repeats.is_news(report.event_seq, block.report_changed):
            self.publish_status(report)
        if block.markers_due:
            outline = robot_outline(cast(HardwareEmulator, self.emulator).robot, *block.truth[1:3])
            self.marker_pub.publish(robot_markers_msg(outline, block.time))

    def block_failed(self, failure: BlockFailure) -> None:
        """A block raised: logged (thinned), the physics fault it latched on /diagnostics (ERROR)."""
        error = failure.error
        if failure.logged:
            self.get_logger().error(f"physics block failed ({failure.count} so far): {type(error).__name__}: "
                                    f"{error}\n{''.join(traceback.format_exception(error))}")
        if failure.latch_error is not None:
            again = failure.latch_error
            self.get_logger().error(f"latching the physics fault failed: {type(again).__name__}: {again}")
        self.diagnostics.set(ERROR, f"physics fault: {type(error).__name__}: {error}; robot held",
                             physics_errors=failure.count)

    def report_pace(self, sim_time: float) -> None:
        """The pace figures on /diagnostics (sim time s, achieved real-time factor, waits for consumers)."""
        pace, consumers = self.wall_pace, self.consumers
        self.diagnostics.values.update(sim_time_s=f"{sim_time:.3f}", achieved_rtf=f"{pace.achieved_rtf:.2f}",
                                       pace_resets=str(pace.behind_resets), consumer_waits=str(consumers.waits),
                                       consumer_waited_s=f"{consumers.waited_s:.2f}",
                                       consumers_run_past=str(consumers.gave_up))

    def _mujoco_warning(self, text: str) -> None:
        """MuJoCo's warning handler (called from the physics thread): the first few and every 100th, logged."""
        self.mujoco_warnings += 1
        if thinned(self.mujoco_warnings, 5, 100):
            self.get_logger().warning(f"MuJoCo: {text} ({self.mujoco_warnings} warnings so far)")

    def publish_state(self, sensors, truth, now, clock: bool = True) -> None:
        """Publish one state period: /clock, the sensors (joint states, IMU, the tracker frames due) and the
        truth (ground_truth/...)."""
        if clock:
            self.clock_pub.publish(cdr.encode_clock(now))
        sensed, imu, frames = sensors
        _, positions, velocities, efforts = sensed
        sensed_cdr = self.state_encoder.encode(now, positions, velocities, efforts)
        self.state_pub.publish(sensed_cdr)
        self.imu_pub.publish(self.imu_encoder.encode(now, imu.angular_velocity, imu.linear_acceleration,
                                                     imu.gyro_variance, imu.accel_variance))
        for frame in frames:
            self.tracker_pub.publish(self.pose_encoder.encode(frame.stamp, frame.position, frame.quaternion))
        true_state, position, quaternion, wrench = truth
        if true_state is sensed:  # the ideal plant: its sensors are the truth, the same bytes
            self.true_state_pub.publish(sensed_cdr)
        else:
            _, positions, velocities, efforts = true_state
            self.true_state_pub.publish(self.state_encoder.encode(now, positions, velocities, efforts))
        self.pose_pub.publish(self.pose_encoder.encode(now, position, quaternion))
        if self.tissue_pub is not None:
            self.tissue_pub.publish(self.wrench_encoder.encode(now, wrench))

    def shutdown(self) -> None:
        """Brake the robot to rest (bounded, STOP_WAIT_S), then stop physics; the emulated robot holds its last
        state (nothing moves after exit)."""
        self._stop_physics(SHUTDOWN)
        if self.emulator is not None:
            self.get_logger().info(f"stopped at sim time {self.emulator.time:.3f} s")


def main(args=None) -> int:
    """Run the hardware_emulator node until SIGINT / SIGTERM; returns the exit code (2: it cannot start)."""
    return run_node(HardwareEmulatorNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
