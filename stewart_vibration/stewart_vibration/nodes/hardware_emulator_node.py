"""hardware_emulator node: the robot in MuJoCo, owning /clock (sim time), as a managed (lifecycle) node.

It publishes what the robot's sensors read (legs/joint_states: encoders, unit sensors and load cells;
platform/imu; platform/tracker_pose), vibration/status (what the units really do), robot_markers, /clock and
/diagnostics, and the truth for judging runs (ground_truth/...: no controller reads it); its commands and
services are nodes.emulator_command_server's. Every topic, its type and QoS: docs/interfaces.md ("ROS graph").

Physics runs in its own thread (emulation.physics_thread), one block of steps per state period, paced by
``real_time_factor`` (0 = as fast as possible; emulation.wall_pace); above real time (or at any rate with
``lockstep``) it also waits for the nodes' estimates (``max_consumer_lag_s``, see emulation.consumer_pace);
commands arrive on the executor thread and are handed over under a lock. The 500 Hz streams are published as
serialized CDR (messages.cdr), the commands are decoded from raw bytes.
"""

from __future__ import annotations

import functools
import threading
from typing import cast

import mujoco
from geometry_msgs.msg import PoseStamped, WrenchStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock as RosClock
from rclpy.clock import ClockType
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState
from visualization_msgs.msg import MarkerArray

from stewart_vibration_interfaces.msg import VibrationUnitsStatus

from ..emulation import command_intake
from ..emulation.emulator import HardwareEmulator
from ..emulation.emulator_reports import StatusRepeats
from ..emulation.emulator_setup import LIVE_PARAMETERS, SETUP_PARAMETERS, build_emulator, set_live_parameter
from ..emulation.physics_thread import PACE_PARAMETERS, Block, BlockSchedule, PhysicsPacing, PhysicsThread
from ..emulation.vibration_status import DEACTIVATED, SHUTDOWN
from ..errors import StewartError
from ..messages import cdr
from ..parameters.tables import HARDWARE_EMULATOR
from ..visualization.robot_outline import robot_outline
from .diagnostics import ERROR, OK, WARN, MalformedInputs
from .emulator_command_server import EmulatorCommandServer
from .emulator_health import EmulatorHealth
from .emulator_messages import StateStreams, robot_markers_msg
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
        self.pacing = PhysicsPacing(**{name: self.get_parameter(name).value for name in PACE_PARAMETERS})
        self.pace_subs: list = []
        self.lock = threading.Lock()
        self.emulator: HardwareEmulator | None = None
        self.physics: PhysicsThread | None = None  # exists while configured
        self.active = False
        self.health = EmulatorHealth(self, lambda: self.emulator)
        # MuJoCo's warnings go to this node's log (not stderr and MUJOCO_LOG.TXT in the working directory); the
        # physics guard sees them in MuJoCo's counters either way
        mujoco.set_mju_user_warning(self.health.mujoco_warning)
        self.status_repeats = StatusRepeats(STATUS_REPEAT_S)
        self.health.set(WARN, "unconfigured (lifecycle: configure, then activate)")
        self.malformed = MalformedInputs(self, self.health.diagnostics)  # e.g. a /clock that is no time (run_node)
        self.commands = EmulatorCommandServer(self)
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
            setup = build_emulator(**{name: param(name).value for name in SETUP_PARAMETERS}, start_time=self.run_clock)
        except (StewartError, ValueError, OSError) as exc:
            self.get_logger().error(f"configure failed: {type(exc).__name__}: {exc}")
            self.health.set(ERROR, f"configure failed: {exc}")
            return TransitionCallbackReturn.FAILURE
        schedule = BlockSchedule.from_rates(param("state_rate_hz").value, param("clock_rate_hz").value,
                                            param("marker_rate_hz").value, STATUS_PERIOD_S,
                                            param("pace_period_s").value)
        with self.lock:
            self.emulator = setup.emulator
            self.physics = PhysicsThread(setup.emulator, self.lock, schedule, self.pacing,
                                         paced_by_consumers=lambda: bool(self.pace_subs))
        # the truth (ground_truth/...) is for judging runs (recorder, run summary, tests); no controller reads it.
        # /clock keeps 1 s of ticks: the ticks of a 20 ms pace period leave in one burst, and a reader (the
        # recorder) that stalls longer than the history loses them
        self.streams = StateStreams(
            clock=self.create_publisher(Clock, "/clock", CLOCK_DEPTH),
            joint_states=self.create_publisher(JointState, "legs/joint_states", STREAM_DEPTH),
            imu=self.create_publisher(Imu, "platform/imu", STREAM_DEPTH),
            tracker=self.create_publisher(PoseStamped, "platform/tracker_pose", 10),
            true_joint_states=self.create_publisher(JointState, "ground_truth/joint_states", STREAM_DEPTH),
            true_pose=self.create_publisher(PoseStamped, "ground_truth/platform_pose", STREAM_DEPTH),
            tissue=None if setup.tissue is None else self.create_publisher(
                WrenchStamped, "ground_truth/tissue_wrench", STREAM_DEPTH))
        self.marker_pub = self.create_publisher(MarkerArray, "robot_markers", 5)
        self.status_pub = self.create_publisher(VibrationUnitsStatus, "vibration/status", STATUS_QOS)
        self._update_pacing()
        self.health.set(OK, "configured (inactive: commands are refused until activate)",
                        physics_rate_hz=param("physics_rate_hz").value, **setup.facts())
        self.get_logger().info(f"configured: {setup.summary()}")
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        physics = cast(PhysicsThread, self.physics)  # activate comes only from configured
        if not physics.running:
            physics.start(self.physics_loop)
        self.active = True
        self.publish_status(cast(HardwareEmulator, self.emulator).status.report)  # says at once it takes commands
        self.health.set(OK, "running")
        self.get_logger().info("active: physics running, commands accepted")
        return super().on_activate(state)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        with self.lock:  # the emulator exists: deactivate comes only from active (configured)
            self.active = False
            cast(HardwareEmulator, self.emulator).halt(DEACTIVATED)
            report = cast(HardwareEmulator, self.emulator).status.report
        self.publish_status(report)  # says at once it refuses commands
        self.health.report(WARN, (
            "inactive: robot stopped safely (vibration ramped out, struts braked to rest within their acceleration "
            "limit, then held); commands refused"))
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._stop_physics(SHUTDOWN)
        self._update_pacing(False)
        for pub in (*self.streams.publishers(), self.marker_pub, self.status_pub):
            self.destroy_publisher(pub)
        with self.lock:
            self.run_clock = cast(HardwareEmulator, self.emulator).time
            self.emulator, self.physics = None, None
        self.health.set(WARN, "unconfigured (cleaned up; a configure goes on from the run's clock)")
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

    def refusal(self) -> str | None:
        """Why commands cannot be taken now, or None."""
        return command_intake.lifecycle_refusal(self.emulator is not None, self.active)

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
                if p.name in PACE_PARAMETERS:  # held by the node, not the emulator: also while unconfigured
                    self.pacing.set(p.name, p.value)
                    self._update_pacing()
                elif p.name in LIVE_PARAMETERS and self.emulator is not None:  # else read again at configure
                    set_live_parameter(self.emulator, p.name, p.value)

    def _update_pacing(self, wanted: bool | None = None) -> None:
        """Subscribe to the consumers' outputs while physics paces itself by them (above real time, or in
        lockstep), unsubscribe otherwise: at 1x the 500 Hz streams would cost CPU for nothing."""
        if wanted is None:
            wanted = self.emulator is not None and self.pacing.waits_for_consumers()
        if wanted and not self.pace_subs:
            self.pace_subs = [self.create_subscription(msg_type, topic, functools.partial(self._heard, topic),
                                                       STREAM_DEPTH, raw=True) for topic, msg_type in PACED_BY.items()]
        elif not wanted and self.pace_subs:
            for sub in self.pace_subs:
                self.destroy_subscription(sub)
            self.pace_subs = []
            self.pacing.consumers.forget()

    def _heard(self, topic: str, data: bytes) -> None:
        stamp = cdr.header_stamp_ns(data)
        if stamp is not None:
            self.pacing.consumers.heard(topic, stamp * 1e-9)

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
            physics.run(self.publish_block, self.health)
        except Exception as exc:  # noqa: BLE001 - last resort: report, the robot is held where it was
            physics.running = False
            self.health.physics_stopped(exc)

    def publish_block(self, block: Block) -> None:
        """One state period out: /clock when due, the sensors and the truth, a newly latched physics fault
        (/diagnostics, the log), the vibration status when it has news, the markers when due."""
        self.streams.publish(block)
        if block.new_fault is not None:
            self.health.fault_latched(block.new_fault, cast(PhysicsThread, self.physics).failures)
        report = block.report
        if report is not None and self.status_repeats.is_news(report.event_seq, block.report_changed):
            self.publish_status(report)
        if block.markers_due:
            outline = robot_outline(cast(HardwareEmulator, self.emulator).robot, *block.truth[1:3])
            self.marker_pub.publish(robot_markers_msg(outline, block.time))

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
