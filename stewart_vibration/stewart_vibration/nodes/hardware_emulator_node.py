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

Physics runs in its own thread, one block of steps per state period, paced by
``real_time_factor`` (0 = as fast as possible); above real time (or at any rate with ``lockstep``)
it also waits for the nodes' estimates (``max_consumer_lag_s``, see emulation.consumer_pace); commands
arrive on the executor thread and are handed over under a lock. The 500 Hz streams are published as
serialized CDR (messages.cdr), the commands are decoded from raw bytes.
"""

from __future__ import annotations

import functools
import threading
import time
import traceback
from typing import cast

import mujoco
import numpy as np
from geometry_msgs.msg import Point, PoseStamped, WrenchStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock as RosClock
from rclpy.clock import ClockType
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import Marker, MarkerArray

from stewart_vibration_interfaces.msg import LegTrajectoryStatus, VibrationUnitsStatus

from ..dynamics.tissue_config import load_tissue_option
from ..emulation.command_size import LEG_TRAJECTORY, VIBRATION_WINDOW, raw_command_refusal
from ..emulation.consumer_pace import ConsumerPace, paces_consumers
from ..emulation.emulator import HardwareEmulator
from ..emulation.physics_guard import PhysicsFault
from ..emulation.plant import load_plant_option
from ..emulation.vibration_status import DEACTIVATED, SHUTDOWN
from ..errors import RefusedError, StewartError
from ..kinematics.robot_config import load_drawing
from ..kinematics.rotations import rotation_from_quaternion
from ..messages import cdr, joint_states, joint_trajectory, stamped_doubles
from ..messages.fields import BASE_FRAME, PLATFORM_FRAME
from ..parameters.tables import HARDWARE_EMULATOR
from ..robot import LEG_NAMES, VIB_NAMES
from ..sim.mjcf import load_simulation_settings
from .diagnostics import ERROR, OK, WARN, Diagnostics, MalformedInputs
from .message_conversions import time_message
from .node_parameters import declare_table
from .outcomes import outcome, outcome_of
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
        self.real_time_factor = self.get_parameter("real_time_factor").value
        self.pace = ConsumerPace(self.get_parameter("max_consumer_lag_s").value)
        self.lockstep = bool(self.get_parameter("lockstep").value)
        self.pace_subs: list = []
        self.lock = threading.Lock()
        self.emulator: HardwareEmulator | None = None
        self.active = False
        self.running = False
        self.thread: threading.Thread | None = None
        self.achieved_rtf = 0.0
        self.behind_resets = 0
        self.physics_errors = 0  # exceptions caught in the physics thread
        self.mujoco_warnings = 0
        # MuJoCo's warnings go to this node's log (not stderr and MUJOCO_LOG.TXT in the working directory); the
        # physics guard sees them in MuJoCo's counters either way
        mujoco.set_mju_user_warning(self._mujoco_warning)
        self._fault_reported: PhysicsFault | None = None  # the physics fault last put on /diagnostics
        self._status_sent = (None, -1, 0.0)  # (state, event_seq, wall time) of the last status message
        self.diagnostics = Diagnostics(self, "hardware emulator")
        self.diagnostics.set(WARN, "unconfigured (lifecycle: configure, then activate)")
        self.rejections = RejectionLog(self)
        self.malformed = MalformedInputs(self, self.diagnostics)  # e.g. a /clock that is no time (run_node)
        self.state_encoder = joint_states.JointStateEncoder(LEG_NAMES + VIB_NAMES)
        self.pose_encoder = stamped_doubles.PoseStampedEncoder(BASE_FRAME)
        self.wrench_encoder = stamped_doubles.WrenchStampedEncoder(BASE_FRAME)
        self.imu_encoder = stamped_doubles.ImuEncoder(PLATFORM_FRAME)
        self.tissue_pub = None
        self.create_subscription(JointTrajectory, "legs/joint_trajectory", self.on_leg_trajectory, 10, raw=True)
        self.trajectory_seq = 0
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
        state_rate = param("state_rate_hz").value
        marker_rate = param("marker_rate_hz").value
        self.period = 1.0 / state_rate
        self.clock_every = max(int(round(state_rate / param("clock_rate_hz").value)), 1)
        self.marker_every = max(int(round(state_rate / marker_rate)), 1) if marker_rate > 0 else 0
        self.status_every = max(int(round(STATUS_PERIOD_S * state_rate)), 1)
        self.blocks_per_wakeup = max(int(round(param("pace_period_s").value * state_rate)), 1)
        with self.lock:
            self.emulator = emulator
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
        if not self.running:
            self.running = True
            self.thread = threading.Thread(target=self.physics_loop, name="physics", daemon=True)
            self.thread.start()
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
        self._brake_to_rest(SHUTDOWN)
        self._stop_physics()
        self._update_pacing(False)
        for pub in (self.state_pub, self.imu_pub, self.tracker_pub, self.true_state_pub, self.pose_pub,
                    self.clock_pub, self.marker_pub, self.status_pub, self.tissue_pub):
            if pub is not None:
                self.destroy_publisher(pub)
        with self.lock:
            self.run_clock = cast(HardwareEmulator, self.emulator).time
            self.emulator = None
        self.diagnostics.set(WARN, "unconfigured (cleaned up; a configure goes on from the run's clock)")
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._brake_to_rest(SHUTDOWN)
        self._stop_physics()
        return TransitionCallbackReturn.SUCCESS

    def _brake_to_rest(self, reason: str, timeout_s: float = STOP_WAIT_S) -> bool:
        """Before physics stops: a safety stop (``HardwareEmulator.halt``) and physics running until the robot is
        at rest, at most ``timeout_s`` of wall time; True when it came to rest (or nothing ran)."""
        emulator = self.emulator
        if emulator is None or not self.running or self.thread is None or not self.thread.is_alive():
            return True
        with self.lock:
            if emulator.at_rest():
                return True
            emulator.halt(reason)
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline and self.running and self.thread.is_alive():
            with self.lock:
                if emulator.at_rest():
                    return True
            time.sleep(0.01)
        self.get_logger().warning(f"{reason}: the robot was still braking after {timeout_s:g} s; physics stops anyway")
        return False

    def _stop_physics(self) -> None:
        self.active = False
        self.running = False
        if self.thread is not None:
            self.thread.join(timeout=2.0)
            self.thread = None

    def _refusal(self) -> str | None:
        """Why commands cannot be taken now, or None."""
        if self.emulator is None:
            return "the hardware emulator is unconfigured (lifecycle: configure, then activate)"
        if not self.active:
            return "the hardware emulator is inactive (lifecycle: activate it)"
        return None

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
                    self.pace.max_lag_s = float(p.value)
                    continue
                if p.name == "lockstep":
                    self.lockstep = bool(p.value)
                    self._pace_reset = True
                    self._update_pacing()
                    continue
                if self.emulator is None and p.name != "real_time_factor":
                    continue  # read again at configure
                if p.name == "real_time_factor":
                    self.real_time_factor = float(p.value)
                    self._pace_reset = True
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
            wanted = self.emulator is not None and paces_consumers(self.real_time_factor, self.lockstep)
        if wanted and not self.pace_subs:
            self.pace_subs = [self.create_subscription(msg_type, topic, functools.partial(self._heard, topic),
                                                       STREAM_DEPTH, raw=True) for topic, msg_type in PACED_BY.items()]
        elif not wanted and self.pace_subs:
            for sub in self.pace_subs:
                self.destroy_subscription(sub)
            self.pace_subs = []
            self.pace.forget()

    def _heard(self, topic: str, data: bytes) -> None:
        stamp = cdr.header_stamp_ns(data)
        if stamp is not None:
            self.pace.heard(topic, stamp * 1e-9)

    # -- commands (executor thread) ------------------------------------------------------
    def on_leg_trajectory(self, data: bytes) -> None:
        """A leg trajectory: taken or refused; the typed answer goes to legs/trajectory_status either way."""
        refusal = self._refusal() or raw_command_refusal(data, LEG_TRAJECTORY)
        if refusal:
            self.rejections.add("leg trajectory", refusal)
            self.answer_trajectory(None, RefusedError("ROBOT_INACTIVE" if self._refusal() else "LIMIT_EXCEEDED",
                                                      refusal))
            return
        traj = None
        try:
            traj = joint_trajectory.decode_joint_trajectory(data)
            # not refused: the emulator exists; it takes the lock only around its snapshot and its commit
            taken = cast(HardwareEmulator, self.emulator).command_struts(traj.names, traj.stamp, traj.times,
                                                                         traj.positions, traj.velocities,
                                                                         traj.accelerations, lock=self.lock)
        except StewartError as exc:
            self.rejections.add("leg trajectory", str(exc))
            self.answer_trajectory(traj, exc)
            return
        self.answer_trajectory(traj, None, taken.end)
        self.diagnostics.set(self._level(OK), self._message("following leg trajectory"),
                             last_leg_trajectory_points=len(traj.times))

    def answer_trajectory(self, traj, refusal: StewartError | None, end_time: float = float("nan")) -> None:
        """Publish the typed answer to one leg trajectory (``traj`` as decoded, or None when unread)."""
        self.trajectory_seq += 1
        final = np.full(6, np.nan)
        if traj is not None and len(traj.times):
            names = list(traj.names)
            for i, name in enumerate(LEG_NAMES):
                if name in names and names.index(name) < traj.positions.shape[1]:
                    final[i] = traj.positions[-1, names.index(name)]
        msg = LegTrajectoryStatus(seq=self.trajectory_seq, accepted=refusal is None,
                                  points=0 if traj is None else len(traj.times), end_time_s=float(end_time))
        msg.final_positions = final
        msg.outcome = outcome("SUCCEEDED", "taken") if refusal is None else outcome_of(refusal)
        msg.header.stamp = time_message(self.emulator.time if self.emulator is not None else 0.0)
        self.trajectory_status_pub.publish(msg)

    def on_vibration(self, data: bytes) -> None:
        refusal = self._refusal() or raw_command_refusal(data, VIBRATION_WINDOW)
        if refusal:
            self.rejections.add("vibration command", refusal)
            return
        try:
            traj = joint_trajectory.decode_joint_trajectory(data)
        except StewartError as exc:
            self.rejections.add("vibration command", str(exc))
            return
        try:
            with self.lock:  # not refused: the emulator exists
                cast(HardwareEmulator, self.emulator).command_vibration(traj.names, traj.stamp, traj.times,
                                                                        traj.positions, traj.velocities,
                                                                        traj.accelerations)
                report = cast(HardwareEmulator, self.emulator).status.report
        except StewartError as exc:
            self.rejections.add("vibration command", str(exc))
            with self.lock:
                report = cast(HardwareEmulator, self.emulator).status.report
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
            self.rejections.add("reset", str(exc))
            return response
        self.publish_status(report)
        self.diagnostics.set(OK, "reset: e-stop cleared, returning home")
        response.success = True
        response.message = f"e-stop cleared; returning home over {duration:.2f} s (sim time)"
        return response

    def _level(self, level):
        """Never report better than ERROR while the e-stop or a physics fault is latched."""
        return ERROR if self.emulator is not None and self.emulator.estopped else level

    def _message(self, message: str) -> str:
        """A latched physics fault or e-stop stays first in the diagnostics message."""
        if self.emulator is not None and self.emulator.fault is not None:
            fault = self.emulator.fault
            return (f"physics fault latched at {fault.time:.3f} s: {fault.reason}; robot held (cleanup + configure to "
                    f"rebuild); {message}")
        if self.emulator is not None and self.emulator.estopped:
            return f"emergency stop latched (call hardware_emulator/reset to clear); {message}"
        return message

    # -- vibration status -------------------------------------------------------------------
    def publish_status(self, report) -> None:
        self.status_pub.publish(vibration_status_msg(report, self.active))
        self._status_sent = (report.state, report.event_seq, time.monotonic())

    def repeat_status(self) -> None:
        """Republish an unchanged status once a second (its amplitudes and times move on)."""
        if self.emulator is None:
            return
        if time.monotonic() - self._status_sent[2] >= STATUS_REPEAT_S * 0.9:
            with self.lock:
                report = self.emulator.status.report
            self.publish_status(report)

    # -- physics (own thread) --------------------------------------------------------------
    def physics_loop(self) -> None:
        """The physics thread: never dies on an exception (``_physics``); a failure it cannot recover from is
        logged and reported."""
        try:
            self._physics()
        except Exception as exc:  # noqa: BLE001 - last resort: report, the robot is held where it was
            self.running = False
            text = f"physics stopped: {type(exc).__name__}: {exc}"
            self.get_logger().error(f"{text}\n{traceback.format_exc()}")
            self.diagnostics.set(ERROR, f"{text}; the robot is held where it was (restart the emulator)")

    def _physics(self) -> None:
        emulator, period = cast(HardwareEmulator, self.emulator), self.period  # physics runs only while configured
        wall0, sim0, cycle = time.monotonic(), emulator.time, 0
        self._pace_reset = False
        self.publish_state(*self._read_state())
        while self.running:
            try:
                with self.lock:
                    emulator.advance(period)
                    state, pose, now = self._read_state()
                    report, changed = (None, False)
                    new_fault = emulator.fault is not None and self._fault_reported is not emulator.fault
                    if cycle % self.status_every == 0 or new_fault:
                        report, changed = emulator.vibration_report()
            except Exception as exc:  # noqa: BLE001 - a failed block: latch a fault, hold the robot, publish on
                self._physics_failed(emulator, exc)
                time.sleep(period)
                continue
            cycle += 1
            if not self.running:
                break  # shutting down: the context may already be gone
            self.publish_state(state, pose, now, clock=cycle % self.clock_every == 0)
            if emulator.fault is not None and self._fault_reported is not emulator.fault:
                self._report_fault(emulator)
            if report is not None and (changed or report.event_seq != self._status_sent[1]):
                self.publish_status(report)
            if self.marker_every and cycle % self.marker_every == 0:
                self.publish_markers(pose, now)
            wall = time.monotonic() - wall0
            self.achieved_rtf = (now - sim0) / wall if wall > 0 else 0.0
            rtf = self.real_time_factor
            if cycle % self.blocks_per_wakeup:
                continue  # the next state period at once: one wake-up per pace period (cold caches cost more)
            if self.pace_subs and self.pace.wait(now, lambda: self.running) > 0:
                self._pace_reset = True  # waited for the estimates: keep the pace from here, do not race
            if self._pace_reset:
                wall0, sim0, self._pace_reset = time.monotonic(), now, False
            elif rtf > 0:
                ahead = (now - sim0) / rtf - wall
                if ahead > 0:
                    time.sleep(ahead)
                elif ahead < -0.5:  # stalled (machine busy): do not race to catch up, keep the pace from here
                    self.behind_resets += 1
                    wall0, sim0 = time.monotonic(), now
            if cycle % 500 == 0:
                self.diagnostics.values.update(sim_time_s=f"{now:.3f}", achieved_rtf=f"{self.achieved_rtf:.2f}",
                                               pace_resets=str(self.behind_resets),
                                               consumer_waits=str(self.pace.waits),
                                               consumer_waited_s=f"{self.pace.waited_s:.2f}",
                                               consumers_run_past=str(self.pace.gave_up))

    def _physics_failed(self, emulator: HardwareEmulator, exc: Exception) -> None:
        """An exception in a physics block: latch a physics fault (the robot is held, time goes on)."""
        self.physics_errors += 1
        if self.physics_errors <= 3 or self.physics_errors % 1000 == 0:
            self.get_logger().error(f"physics block failed ({self.physics_errors} so far): {type(exc).__name__}: "
                                    f"{exc}\n{traceback.format_exc()}")
        try:
            with self.lock:
                emulator.latch_fault(f"{type(exc).__name__} in the physics thread: {exc}")
        except Exception as again:  # noqa: BLE001 - the fault is reported below whatever happens
            self.get_logger().error(f"latching the physics fault failed: {type(again).__name__}: {again}")
        self.diagnostics.set(ERROR, f"physics fault: {type(exc).__name__}: {exc}; robot held",
                             physics_errors=self.physics_errors)

    def _mujoco_warning(self, text: str) -> None:
        """MuJoCo's warning handler (called from the physics thread): the first few and every 100th, logged."""
        self.mujoco_warnings += 1
        if self.mujoco_warnings <= 5 or self.mujoco_warnings % 100 == 0:
            self.get_logger().warning(f"MuJoCo: {text} ({self.mujoco_warnings} warnings so far)")

    def _report_fault(self, emulator: HardwareEmulator) -> None:
        """Put a newly latched physics fault on /diagnostics (ERROR, with its time and reason) and the log."""
        fault = cast(PhysicsFault, emulator.fault)  # called when one is latched
        self._fault_reported = fault
        self.get_logger().error(f"physics fault at sim time {fault.time:.3f} s: {fault.reason}; the robot is held at "
                                "its last good state (cleanup + configure to rebuild)")
        self.diagnostics.set(ERROR, self._message("physics stopped following the commands"),
                             physics_fault=fault.reason, physics_fault_time_s=f"{fault.time:.6f}",
                             physics_errors=self.physics_errors)

    def _read_state(self):
        """(sensors: (joint state tuple, IMU sample, tracker frames), truth: (joint state tuple, platform
        position, quaternion, tissue wrench), time) under the lock."""
        emulator = self.emulator
        position, quaternion = emulator.sim.platform_position_quaternion()
        state = emulator.joint_state()
        sensors = (state, emulator.imu_sample(quaternion), emulator.tracker_frames(position, quaternion))
        return sensors, (emulator.true_joint_state(state), position, quaternion, emulator.tissue_wrench), emulator.time

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

    def publish_markers(self, pose, now) -> None:
        """robot_markers, all in frame base (no /tf needed; the recorder records them, so a run's MCAP shows
        the robot in Foxglove's 3D panel): the legs (base hinge -> platform hinge), the platform and base
        hinge polygons, and every hinge as a sphere."""
        robot = cast(HardwareEmulator, self.emulator).robot  # called from the physics loop: configured
        position, quaternion = pose[1:3]
        rot = rotation_from_quaternion(quaternion)
        tips = position + robot.platform_hinges @ rot.T
        sec, nanosec = cdr.stamp_parts(now)

        def marker(ns, marker_id, kind, width, rgb: tuple[float, float, float], points):
            m = Marker(ns=ns, id=marker_id, type=kind, action=Marker.ADD)
            m.header.frame_id = BASE_FRAME
            m.header.stamp.sec, m.header.stamp.nanosec = sec, nanosec
            m.scale.x = m.scale.y = m.scale.z = width  # line width (lines use x only), sphere diameter
            m.color.r, m.color.g, m.color.b, m.color.a = (*rgb, 1.0)
            m.points = [Point(x=float(p[0]), y=float(p[1]), z=float(p[2])) for p in points]
            return m

        base = robot.base_hinges
        self.marker_pub.publish(MarkerArray(markers=[
            marker("legs", 0, Marker.LINE_LIST, 0.006, (0.2, 0.5, 0.9), np.stack([base, tips], axis=1).reshape(-1, 3)),
            marker("platform", 1, Marker.LINE_STRIP, 0.004, (0.9, 0.5, 0.1), np.vstack([tips, tips[:1]])),
            marker("base", 2, Marker.LINE_STRIP, 0.004, (0.55, 0.57, 0.6), np.vstack([base, base[:1]])),
            marker("hinges", 3, Marker.SPHERE_LIST, 0.012, (0.25, 0.25, 0.28), np.vstack([base, tips])),
        ]))

    def shutdown(self) -> None:
        """Brake the robot to rest (bounded, STOP_WAIT_S), then stop physics; the emulated robot holds its last
        state (nothing moves after exit)."""
        self._brake_to_rest(SHUTDOWN)
        self._stop_physics()
        if self.emulator is not None:
            self.get_logger().info(f"stopped at sim time {self.emulator.time:.3f} s")


class RejectionLog:
    """Rejected commands: every one counted and on /diagnostics (WARN, never below an e-stop's ERROR);
    the log gets the first of each reason and then at most one line per second."""

    def __init__(self, node: HardwareEmulatorNode, period_s: float = 1.0):
        self.node, self.period_s = node, period_s
        self.count = 0
        self._last_log: dict[tuple[str, str], float] = {}

    def add(self, what: str, reason: str) -> None:
        self.count += 1
        node = self.node
        key = (what, reason.split(":")[0])
        now = time.monotonic()
        if now - self._last_log.get(key, -np.inf) >= self.period_s:
            self._last_log[key] = now
            node.get_logger().warning(f"rejected {what}: {reason} ({self.count} rejections so far)")
        node.diagnostics.set(node._level(WARN), node._message(f"rejected {what}: {reason}"),
                             last_rejection=reason, rejections=self.count)


def main(args=None) -> int:
    """Run the hardware_emulator node until SIGINT / SIGTERM; returns the exit code (2: it cannot start)."""
    return run_node(HardwareEmulatorNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
