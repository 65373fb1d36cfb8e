"""vibration planner node: a vibration session (action) -> self-contained vib_* command windows.

Action vibration_planner/vibrate (stewart_vibration_interfaces/action/Vibrate): the goal carries the
vibration (direction and frame, amplitude or acceleration, frequency, phase, duration, ramp); the node's
parameters are only the streaming's timing (lookahead_s, window_period_s, sample_period_s, lead_s,
start_lead_s, max_lookahead_s, pose_timeout_s). Feedback at 10 Hz: the units' state, the plan, the time
since t0 and what the sensors show delivered (frequency, amplitude along the direction, direction error,
the legs' phase spread; analysis.delivered). Result: the outcome (a code of the one table), the plan,
the active time and the cycles delivered. Cancel = a ramp-out over ramp_s. One vibration at a time: a goal
while one runs ends at once with BUSY.

Topics (relative): sub platform/pose_estimate (PoseStamped, base; while a vibration runs its last 128 are kept
for the delivered figures, the legs' phases from the lengths they imply), vibration/status (VibrationUnitsStatus
from the hardware emulator: what the units really do; a malformed one is counted on /diagnostics and ignored,
see messages.status_values); pub vibration/joint_trajectory (JointTrajectory vib_1..vib_6: positions m,
velocities m/s, accelerations m/s^2; header.stamp = the vibration's common start time t0, time_from_start
relative to t0). Diagnostics on /diagnostics.

The windows and their timing are vibration.streaming (pure): a finite vibration
that fits ``max_lookahead_s`` is sent whole in its first window; otherwise every
``window_period_s`` a window with ``lookahead_s`` of vibration and a ramp-out
tail, so if no later window arrives the units ramp out smoothly on their own.

States: idle, running, stopping, aborted (with the reason). A goal starts from idle or aborted when
vibration.start_gate allows it (no vibration running, no latched e-stop, units at rest by a recent
status, the planner's clock running and the robot's, a recent pose estimate) and the settings pass
vibration.settings.start_check; otherwise it ends at once with the refusal's outcome.
t0 = the goal's arrival (sim clock, at least the fresh pose estimate's stamp) + start_lead_s
(wall seconds: scaled to sim seconds by the sim clock's rate when it runs faster than real time). The planner
aborts -- stops streaming, says why on /diagnostics (ERROR for an e-stop, WARN otherwise), in its state and in
the goal's outcome -- when the emulator refuses one of its windows (ROBOT_REFUSED), e-stops
(EMERGENCY_STOPPED, PHYSICS_FAULT), reports the units stopped or idle before the planned end (STOPPED_EARLY, or
the outcome of the robot's own safety ramp: ROBOT_INACTIVE for a deactivate, UNIT_TRAVEL_STOPPED for a unit's
protection),
or when it was itself held up past the buffered look-ahead (HELD_UP: the units have begun their ramp-out;
judged on the first tick after the stall by the wall clock at the measured sim rate, since the sim clock is
stale until the /clock sent meanwhile is taken).
"""

from __future__ import annotations

import time
from collections import deque
from typing import cast

import numpy as np
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from sensor_msgs.msg import Imu, JointState
from trajectory_msgs.msg import JointTrajectory

from stewart_vibration_interfaces.action import IdentifyVibrationUnits, Vibrate
from stewart_vibration_interfaces.msg import VibrationUnitsStatus

from ..analysis.delivered import delivered_vibration
from ..errors import MalformedMessageError, RefusedError, StewartError
from ..kinematics import inverse_kinematics
from ..kinematics.robot_config import load_robot
from ..kinematics.rotations import rotation_from_rpy
from ..messages import joint_states, joint_trajectory, stamped_doubles
from ..messages.stamped import pose_from_cdr, poses_from_cdr
from ..messages.status_values import vibration_report_from_cdr
from ..output_files import writable_output
from ..parameters.tables import VIBRATION_PLANNER
from ..robot import VIB_NAMES
from ..runtime.sim_clock import ClockRate
from ..vibration.closed_loop import ClosedLoop, closed_loop_for
from ..vibration.identification_session import IdentificationSession, identification_steps
from ..vibration.settings import STREAM_KEYS, default_settings, settings_reason, start_check, start_refusal
from ..vibration.start_gate import BUSY_STATES, UNITS_MOVING, check_can_start, robot_stop
from ..vibration.streaming import StreamInterrupted, VibrationStream
from ..vibration.unit_identification import FILE_KIND, load_identification_option, quality_problems, save_identification
from ..vibration.waveform import envelope, fade_out
from .diagnostics import ERROR, OK, WARN, Diagnostics, MalformedInputs, reject
from .node_parameters import declare_table
from .outcomes import end_goal, outcome
from .run_loop import STATUS_QOS, run_node
from .vibration_goal import UNIT_STATES, goal_settings, plan_message

POLL_PERIOD_S = 0.01  # wall-clock polling of the sim clock for the streaming
STALL_S = 0.1  # a tick this late means the process was held up: skip it (the sim clock is stale)
STATUS_STALE_S = 2.5  # wall s: the emulator repeats its status every second, so an older one is stale
IMU_QOS = QoSProfile(depth=500, reliability=ReliabilityPolicy.RELIABLE)  # 1 s of samples: bursts of 10 every 20 ms
# an identification step's window is sent this long (sim s) before it starts: a planner held up for less
# delays nothing (the robot queues it behind the step it runs)
IDENTIFICATION_QUEUE_S = 1.0
REST_REPORT_WAIT_S = 3.0  # sim s after an identification's last step for the robot's report of its units at rest
FEEDBACK_PERIOD_S = 0.1  # wall s between a goal's feedback messages
DELIVERED_WINDOW = 128  # the last samples (~0.25 s at 500 Hz) the delivered figures are judged over


class VibrationPlannerNode(Node):
    """Thin adapter over stewart_vibration.vibration (start_gate, start_check, VibrationStream) and
    analysis.delivered, behind the vibrate action."""

    def __init__(self):
        super().__init__("vibration_planner")
        declare_table(self, VIBRATION_PLANNER)
        self.robot = load_robot(self.get_parameter("robot_config").value or None)
        self.add_on_set_parameters_callback(self.on_set_parameters)
        self.add_post_set_parameters_callback(self.after_set_parameters)
        reason = settings_reason(self.robot, self.settings_with({}))
        if reason:
            raise ValueError(f"invalid initial parameters: {reason}")
        self.identification = load_identification_option(self.get_parameter("identification_file").value)
        self._identification_read: tuple[str, object] = ("", None)  # (path, what it held) of the last set's check

        self.diagnostics = Diagnostics(self, "vibration planner")
        self.malformed = MalformedInputs(self, self.diagnostics)
        self.state = "idle"
        self.last_error = ""
        self.stream: VibrationStream | None = None
        self.loop: ClosedLoop | None = None  # the running vibration's closed loop (closed_loop)
        self._imu_subscription = None
        self.run = None  # dict: settings, t0 (s), next_send (s), seen (s from t0: the last tick's sim time),
        # goal (its handle), done (Future of (outcome name, message, run)), plan (VibrationPlan), next_feedback
        # (wall s), stream
        self.pose_data = None  # raw PoseStamped bytes and their receive time (monotonic wall clock, s:
        # the sim clock may be stale when this process resumes from a stall)
        self.recent_poses: deque = deque(maxlen=DELIVERED_WINDOW)  # raw, while a vibration runs
        self.emulator = None  # latest VibrationReport from vibration/status
        self.emulator_received = 0.0  # when it arrived (monotonic wall clock, s)
        self.seen_event = 0
        self._pose_seen = 0
        self._last_tick = time.monotonic()
        # leads are wall-clock margins (a window must reach the emulator in time): faster than real time
        # they are scaled to as many more sim seconds
        self.clock_rate = ClockRate()
        self._last_rate_sample = 0.0
        self.pub = self.create_publisher(JointTrajectory, "vibration/joint_trajectory", 10)
        self.create_subscription(PoseStamped, "platform/pose_estimate", self.on_pose, 10, raw=True)
        self.create_subscription(VibrationUnitsStatus, "vibration/status", self.on_status, STATUS_QOS, raw=True)
        self.action = ActionServer(self, Vibrate, "vibration_planner/vibrate", execute_callback=self.execute,
                                   goal_callback=lambda goal: GoalResponse.ACCEPT, cancel_callback=self.on_cancel)
        self.identifying: dict | None = None  # the identification run: session, t0, goal, done, path, next_feedback
        self._joint_state_subscription = None
        self._joint_states = joint_states.JointStateDecoder()
        self.identify_action = ActionServer(
            self, IdentifyVibrationUnits, "vibration_planner/identify_vibration_units",
            execute_callback=self.identify_execute, goal_callback=lambda goal: GoalResponse.ACCEPT,
            cancel_callback=lambda goal: CancelResponse.ACCEPT)
        self.create_timer(POLL_PERIOD_S, self.tick, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.diagnostics.watch("platform/pose_estimate", 1.0, "from kinematics")
        self.diagnostics.watch("vibration/status", 3.0, "from hardware_emulator")
        self._report(OK, "idle")
        self.get_logger().info(f"vibration planner ready (robot {self.robot.source})")

    # -- parameters -----------------------------------------------------------------
    def settings_with(self, vibration: dict) -> dict:
        """Every setting: the streaming parameters, and ``vibration``'s keys over the defaults of the rest."""
        s = default_settings(self.robot)
        s.update({name: self.get_parameter(name).value for name in STREAM_KEYS})
        s.update(vibration)
        return s

    def on_set_parameters(self, params) -> SetParametersResult:
        s = self.settings_with({})
        for p in params:
            if p.name in s:
                s[p.name] = p.value
        try:
            reason = settings_reason(self.robot, s)
        except (TypeError, ValueError) as exc:
            reason = f"invalid parameter value: {exc}"
        for p in params:
            if p.name == "identification_file" and not reason:
                try:  # read once here; after_set_parameters takes what was read
                    self._identification_read = (p.value, load_identification_option(p.value))
                except StewartError as exc:
                    reason = f"identification_file: {exc}"
        if reason:
            if hasattr(self, "diagnostics"):
                reject(self, self.diagnostics, "parameters", reason)
            return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def after_set_parameters(self, params) -> None:
        """A new identification_file (already checked) is loaded for the next vibration."""
        for p in params:
            if p.name == "identification_file":
                path, read = self._identification_read
                self.identification = read if path == p.value else load_identification_option(p.value)
                self.get_logger().info(f"identification: {p.value or 'none (uncompensated)'}")

    # -- inputs ------------------------------------------------------------------------
    def now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def on_pose(self, data: bytes) -> None:
        """Keep the latest estimate (500 Hz: decoded only when a vibration starts or feedback is due)."""
        self.pose_data = (data, time.monotonic())
        if self.run is not None:
            self.recent_poses.append(data)
        self._pose_seen += 1
        if self._pose_seen % 50 == 1:  # the freshness watch needs no more than a few per second
            self.diagnostics.seen("platform/pose_estimate")

    def _ensure_imu_subscription(self) -> None:
        """Subscribe platform/imu the first time a closed loop needs it (500 Hz: not before)."""
        if self._imu_subscription is None:
            self._imu_subscription = self.create_subscription(Imu, "platform/imu", self.on_imu, IMU_QOS, raw=True)
            self.diagnostics.watch("platform/imu", 1.0, "from hardware_emulator (closed loop)")

    def on_imu(self, data: bytes) -> None:
        """A platform IMU sample for the closed loop of the running vibration (else ignored)."""
        loop, run, ident = self.loop, self.run, self.identifying
        if ident is not None:
            sample = self.malformed.read("platform/imu", stamped_doubles.decode_imu, data)
            if sample is not None:
                ident["session"].add_imu(sample[0] - ident["t0"], sample[3], sample[2])
            return
        if loop is None or run is None or self.state != "running":
            return
        sample = self.malformed.read("platform/imu", stamped_doubles.decode_imu, data)
        if sample is None:
            return
        stamp, _, rate, accel = sample
        reason = loop.add_imu(stamp - run["t0"], accel, rate)
        if reason:
            self._abort_delivery(reason)

    def on_joint_states(self, data: bytes) -> None:
        """The units' sensor readings for the identification run (else ignored)."""
        ident = self.identifying
        if ident is None:
            return
        state = self.malformed.read("legs/joint_states", self._joint_states.decode, data)
        if state is None:
            return
        index = {name: k for k, name in enumerate(state.names)}
        if all(name in index for name in VIB_NAMES) and state.position.size == len(state.names):
            ident["session"].add_units(state.stamp - ident["t0"], state.position[[index[n] for n in VIB_NAMES]])

    async def identify_execute(self, goal_handle):
        """The identification run (IdentifyVibrationUnits): refuse it with its outcome, or run it to its end."""
        goal = goal_handle.request
        result = IdentifyVibrationUnits.Result()
        try:
            self._start_identification(goal, goal_handle)
        except StewartError as exc:
            self.last_error = str(exc)
            reject(self, self.diagnostics, "identify", str(exc))
            goal_handle.abort()
            result.outcome = outcome(exc.outcome, str(exc))
            return result
        name, message, path, problems, duration = await cast(dict, self.identifying)["done"]
        self.identifying = None
        self.state = "idle"
        if self._joint_state_subscription is not None:  # 500 Hz the planner needs only while identifying
            self.destroy_subscription(self._joint_state_subscription)
            self._joint_state_subscription = None
        result.outcome, result.path, result.problems, result.duration_s = outcome(name, message), path, problems, \
            duration
        end_goal(goal_handle, name)
        self._report(OK, "idle")
        return result

    def _start_identification(self, goal, goal_handle) -> None:
        """Check the goal, then that the run may start now, at the current pose, and start it; StewartError if
        not."""
        steps, amplitude = identification_steps(tuple(goal.frequencies_hz), float(goal.amplitude_m),
                                                self.robot.vibration_unit)
        path = writable_output(goal.output_path or f"vibration_identification_{time.strftime('%Y%m%d_%H%M%S')}.yaml",
                               "vibration identification", lambda tree: tree.get("kind") == FILE_KIND)
        s = self.settings_with({})
        now = self._check_can_start(s["pose_timeout_s"])
        _, pose = pose_from_cdr(cast(tuple, self.pose_data)[0], "pose estimate")
        lead = self.clock_rate.wall_margin(s["start_lead_s"])
        self.identifying = {
            "session": IdentificationSession(steps, amplitude, pose), "t0": now + lead, "goal": goal_handle,
            "done": Future(), "path": path,
            "next_feedback": 0.0, "queue_s": max(lead, IDENTIFICATION_QUEUE_S),
            "date": time.strftime("%Y-%m-%d %H:%M:%S")}
        self.state = "identifying"
        self.seen_event = self.emulator.event_seq if self.emulator is not None else 0
        self._ensure_imu_subscription()
        if self._joint_state_subscription is None:
            self._joint_state_subscription = self.create_subscription(JointState, "legs/joint_states",
                                                                      self.on_joint_states, IMU_QOS, raw=True)
        self.get_logger().info(f"identifying the vibration units: {len(steps)} steps at "
                               f"{sorted({x.frequency for x in steps})} Hz, {amplitude * 1e6:g} um, "
                               f"{steps[-1].end:.1f} s")
        self._report(OK, "identifying")

    def _identification_tick(self, ident: dict) -> None:
        """Send the steps' windows when due, the feedback at 10 Hz, and finish after the last step."""
        session, t0, goal_handle = ident["session"], ident["t0"], ident["goal"]
        rel = self.now_s() - t0
        if goal_handle.is_cancel_requested and not ident["done"].done():
            ident["done"].set_result(("CANCELED", "cancelled: no further step, nothing written", "", [], 0.0))
            return
        for start, times, pos, vel, acc in session.due_windows(rel, ident["queue_s"]):
            self.pub.publish(joint_trajectory.encode_joint_trajectory(VIB_NAMES, t0 + start, times, pos, vel, acc))
        wall = time.monotonic()
        if wall >= ident["next_feedback"]:
            ident["next_feedback"] = wall + FEEDBACK_PERIOD_S
            step, steps, unit, frequency = session.progress(rel)
            goal_handle.publish_feedback(IdentifyVibrationUnits.Feedback(step=step, steps=steps, unit=unit,
                                                                         frequency_hz=frequency))
        if rel < session.end + 0.1 or ident["done"].done():
            return
        report = self.emulator  # ends once the robot reports its units at rest after the last step (a vibration
        at_rest = report is not None and report.time >= t0 + session.end and report.state not in BUSY_STATES
        if not at_rest and rel < session.end + REST_REPORT_WAIT_S:  # started next is refused before that)
            return
        try:
            found = session.identification(self.robot.gravity, float(self.get_parameter("imu_average_s").value),
                                           float(self.get_parameter("unit_sensor_latency_s").value),
                                           {"date": ident["date"], "method": "stepped sine, unit sensors and IMU"})
        except StewartError as exc:
            ident["done"].set_result(("IDENTIFICATION_REJECTED", f"no identification: {exc}", "", [str(exc)],
                                      session.end))
            return
        problems = quality_problems(found)
        if problems:
            ident["done"].set_result(("IDENTIFICATION_REJECTED", f"{len(problems)} problems, first: {problems[0]}",
                                      "", problems, session.end))
            return
        try:
            path = str(save_identification(ident["path"], found))
        except OSError as exc:
            ident["done"].set_result(("INVALID_ARGUMENT", f"could not write {ident['path']}: {exc}", "",
                                      [f"not written: {exc}"], session.end))
            return
        self.set_parameters([Parameter("identification_file", value=path)])
        ident["done"].set_result(("SUCCEEDED", f"identified at {len(found.frequencies)} frequencies: {path}", path,
                                  [], session.end))

    def _abort_delivery(self, reason: str) -> None:
        """The closed loop's abort: ramp out now, the goal ends DELIVERY_LIMIT with ``reason``."""
        self._stop_streaming()
        self.loop = None
        self.abort(reason, WARN, "DELIVERY_LIMIT")

    def on_status(self, data: bytes) -> None:
        """The emulator's vibration/status (raw). A malformed one is counted and ignored: the planner keeps the
        last good report (it neither believes the units run nor aborts for it)."""
        report = self.malformed.read("vibration/status", vibration_report_from_cdr, data)
        if report is None:
            return
        self.diagnostics.seen("vibration/status")
        self.emulator = report
        self.emulator_received = time.monotonic()
        if self.state == "identifying":
            self._follow_identification(report)
            return
        if self.state not in ("running", "stopping"):
            self.seen_event = report.event_seq
            return
        t0 = self.run["t0"]
        if report.state in UNITS_MOVING or report.since > t0:  # moving, or changed state since t0 (a keep-last-1
            self.run["confirmed"] = True                         # subscriber may see only the idle at the end)
        new_event = report.event_seq != self.seen_event
        self.seen_event = report.event_seq
        stop = robot_stop(report, t0, new_event)
        if stop is not None:
            self.abort(stop[1], ERROR if report.state == "estopped" else WARN, stop[0])
        elif report.state == "idle" and report.since > t0:
            end = cast(VibrationStream, self.stream).planned_end  # running or stopping: a stream is set
            if self.state == "running" and (end is None or report.since < t0 + end - 0.05):
                self.abort(f"the vibration units went idle at {report.since:.3f} s, before the planned end "
                           f"({'until stop' if end is None else f'{t0 + end:.3f} s'}): {report.reason}", WARN,
                           "STOPPED_EARLY")

    def _follow_identification(self, report) -> None:
        """End the identification run when the robot stopped it (start_gate.robot_stop): nothing is written."""
        new_event = report.event_seq != self.seen_event
        self.seen_event = report.event_seq
        ident = self.identifying
        if ident is None or ident["done"].done():
            return
        stop = robot_stop(report, ident["t0"], new_event)
        if stop is not None:
            name, reason = stop
            ident["done"].set_result((name, f"identification stopped, nothing written: {reason}", "", [reason],
                                      max(report.since - ident["t0"], 0.0)))

    # -- state ---------------------------------------------------------------------------
    def _report(self, level, message: str) -> None:
        run = self.run or {}
        self.diagnostics.set(level, message, state=self.state, last_error=self.last_error or "none",
                             windows_sent=self.stream.windows_sent if self.stream else 0,
                             t0_s=f"{run['t0']:.6f}" if run else "")

    def abort(self, reason: str, level, outcome_name: str) -> None:
        """Stop streaming; state 'aborted: reason' until the next start; the goal ends with ``outcome_name``."""
        self.state = f"aborted: {reason}"
        self.last_error = reason
        self._finish(outcome_name, reason)
        self.get_logger().error(f"vibration aborted: {reason}") if level == ERROR else \
            self.get_logger().warning(f"vibration aborted: {reason}")
        self._report(level, self.state)

    def _finish(self, outcome_name: str, message: str) -> None:
        """End the running goal (its execute returns the result) and forget the run."""
        run, self.run = self.run, None
        self.recent_poses.clear()
        if run is not None and not run["done"].done():
            run["ended"] = self.now_s()
            run["done"].set_result((outcome_name, message, run))

    # -- the vibrate action -------------------------------------------------------------------
    async def execute(self, goal_handle):
        """One vibration session: refuse it with its outcome, or run it until it ends, is cancelled or aborts."""
        settings = self.settings_with(goal_settings(goal_handle.request))
        try:
            self._start(settings, goal_handle)
        except Exception as exc:  # noqa: BLE001 - every refusal (and a defect) ends the goal with its code
            if isinstance(exc, StewartError):
                name, reason = exc.outcome, str(exc) if isinstance(exc, RefusedError) else start_refusal(exc, settings)
            else:
                name, reason = "INTERNAL_ERROR", f"{type(exc).__name__}: {exc}"
                self.get_logger().error(f"vibrate goal failed: {reason}")
            self.last_error = reason
            reject(self, self.diagnostics, "start", reason)
            goal_handle.abort()
            result = Vibrate.Result()
            result.outcome = outcome(name, reason)
            return result
        name, message, run = await cast(dict, self.run)["done"]
        result = Vibrate.Result(plan=run["plan"])
        result.outcome = outcome(name, message)
        result.active_s, result.cycles_delivered = self._delivered_dose(run)
        result.loop_corrections, result.demand_correction = loop_figures(run)
        end_goal(goal_handle, name)
        return result

    def _check_can_start(self, pose_timeout_s: float) -> float:
        """The clock now (s) if the robot may be driven now (start_gate.check_can_start); RefusedError if not."""
        emulator = self.emulator
        now = self.now_s()
        pose_age = None if self.pose_data is None else time.monotonic() - self.pose_data[1]
        check_can_start(self.state, emulator.state if emulator else None,
                        time.monotonic() - self.emulator_received, STATUS_STALE_S,
                        emulator.time if emulator else None, now, pose_age, pose_timeout_s,
                        self.clock_rate.rate(), emulator.active if emulator else True)
        return now

    def _start(self, settings: dict, goal_handle) -> None:
        """Check and start the vibration of ``settings`` for ``goal_handle``; RefusedError / StewartError if not."""
        now = self._check_can_start(settings["pose_timeout_s"])
        data, _ = cast(tuple, self.pose_data)
        try:
            pose_stamp, pose = pose_from_cdr(data, "pose estimate")
        except MalformedMessageError as exc:
            self.malformed.refuse("platform/pose_estimate", exc)
            raise RefusedError("NOT_READY", f"pose estimate unusable: {exc}") from None
        # just resumed from a stall, this process may not have taken the latest /clock yet: the
        # fresh pose estimate's stamp (sim time) bounds the present from below
        now = max(now, pose_stamp)
        closed = bool(self.get_parameter("closed_loop").value)
        started = start_check(self.robot, pose, settings, self.clock_rate.wall_margin,  # wall s -> sim s
                              identification=self.identification, closed_loop=closed)
        plan, stream, first = started.plan, started.stream, started.first
        t0 = now + started.start_lead
        self.stream = stream
        self.loop = None
        loop_note = ""
        if closed and started.compensated and started.schedule is not None and self.identification is not None:
            self._ensure_imu_subscription()
            self.loop = closed_loop_for(
                self.robot, plan, started.schedule, stream, self.identification,
                rotation_from_rpy(np.asarray(pose)[3:]), settings["ramp_s"],
                float(self.get_parameter("loop_gain").value), float(self.get_parameter("imu_average_s").value),
                float(self.get_parameter("imu_silence_s").value))
            loop_note = "; closed loop on the platform IMU"
        elif closed:
            loop_note = "; no closed loop: it needs the units' identification at this pose"
        plan_msg = plan_message(plan, settings, t0)
        # seen: the last sim time (s from t0) a tick saw, from which a stall is judged
        self.run = {"settings": settings, "t0": t0, "next_send": now + settings["window_period_s"], "seen": now - t0,
                    "goal": goal_handle, "done": Future(), "plan": plan_msg, "next_feedback": 0.0, "stream": stream,
                    "loop": self.loop}
        self.state, self.last_error = "running", ""
        self.seen_event = self.emulator.event_seq if self.emulator is not None else 0
        self.publish(first)
        self.get_logger().info(
            f"vibrating: {plan.frequency:g} Hz, platform amplitude {plan.amplitude * 1e6:.3f} um along "
            f"{np.round(plan.direction, 6).tolist()} (base frame), t0 = {t0:.6f} s, ramp {settings['ramp_s']} s, "
            f"duration {settings['duration_s'] or 'until cancelled'} s{' (sent whole)' if stream.finished else ''}; "
            f"{started.compensation}{loop_note}")
        self.diagnostics.set(OK, "running", frequency_hz=plan.frequency, amplitude_um=plan.amplitude * 1e6,
                             gains=np.round(plan.gains, 6).tolist(),
                             leg_amplitudes_um=np.round(plan.leg_amplitudes * 1e6, 3).tolist())
        self._report(OK, "running")

    def on_cancel(self, goal_handle) -> CancelResponse:
        """Cancel = ramp out (the goal ends CANCELED when the units are at rest); a goal already ending is let be."""
        run = self.run
        if run is None or run["goal"] is not goal_handle:
            return CancelResponse.ACCEPT
        if self.state == "running":
            self._stop_streaming()
        return CancelResponse.ACCEPT

    def _stop_streaming(self) -> None:
        run = cast(dict, self.run)
        stream = cast(VibrationStream, self.stream)
        t0 = run["t0"]
        window = stream.stop_window(self.now_s() - t0)
        self.state = "stopping"
        if window is not None:
            self.publish(window)
        if window is None:
            message = f"the vibration already ends at {t0 + stream.rest_at:.4f} s; letting it ramp out"
        elif cast(float, stream.stop_at) <= 0.0:
            message = f"stopping before the vibration began at {t0:.4f} s: the units stay at rest"
        else:
            message = (f"stopping: ramp-out from {t0 + stream.stop_at:.4f} s over {run['settings']['ramp_s']} s, at "
                       f"rest at {t0 + window.rest_at:.4f} s")
        self._report(OK, "stopping")
        self.get_logger().info(message)

    def _feedback(self, run: dict) -> None:
        """The goal's feedback: the units' state, the plan, the time since t0 and the delivered figures."""
        feedback = Vibrate.Feedback(plan=run["plan"], elapsed_s=self.now_s() - run["t0"])
        report = self.emulator
        feedback.state = UNIT_STATES.get(report.state if report else "idle", 0)
        plan = cast(VibrationStream, self.stream).plan
        poses = poses_from_cdr(list(self.recent_poses), "pose estimate")
        try:
            # the legs' hinge-to-hinge lengths the estimate implies: their vibration is the units' (the struts
            # hold still), and this needs no second 500 Hz stream
            lengths = inverse_kinematics(self.robot, poses.values, check_limits=False)
            delivered = delivered_vibration(poses.stamps, poses.values[:, :3], poses.stamps, lengths, plan.frequency,
                                            plan.direction, plan.leg_amplitudes, plan.leg_phases)
        except StewartError:  # a non-finite sample: say nothing this time
            delivered = None
        if delivered is not None and delivered.known:
            feedback.frequency_hz = delivered.frequency_hz
            feedback.delivered_amplitude_m = delivered.amplitude_m
            feedback.direction_error_rad = delivered.direction_error_rad
            feedback.phase_spread_rad = delivered.phase_spread_rad
        feedback.loop_corrections, feedback.demand_correction = loop_figures(run)
        run["goal"].publish_feedback(feedback)

    def _delivered_dose(self, run: dict) -> tuple[float, float]:
        """(active s: from t0 to the run's end or the units' commanded rest, whichever is first; cycles: the
        commanded envelope's integral over that time times the frequency) of a finished run."""
        s, stream = run["settings"], run["stream"]  # the run's own: another may have begun since
        end = min(run.get("ended", run["t0"]), run["t0"] + stream.rest_at)
        active = max(end - run["t0"], 0.0)
        if active <= 0:
            return 0.0, 0.0
        times = np.linspace(0.0, active, max(int(active / 1e-3), 2))
        weight = envelope(times, s["duration_s"] if s["duration_s"] > 0 else None, s["ramp_s"])[0]
        if stream.stop_at is not None:  # a cancel's ramp-out
            weight = weight * fade_out(times, stream.stop_at, s["ramp_s"])[0]
        return float(active), float(np.trapezoid(weight, times) * stream.plan.frequency)

    # -- streaming ---------------------------------------------------------------------------
    def tick(self) -> None:
        wall = time.monotonic()
        gap, self._last_tick = wall - self._last_tick, wall
        if gap <= STALL_S and wall - self._last_rate_sample >= 0.05:
            self._last_rate_sample = wall
            self.clock_rate.add(wall, self.now_s())
        if self.identifying is not None:
            self._identification_tick(self.identifying)
            return
        run = self.run
        if run is None:
            return
        if gap > STALL_S:
            # this process was held up (SIGSTOP, a busy machine): the sim clock it sees is stale until the
            # /clock sent meanwhile is taken, which may not be soon. Judge by the wall clock now (at the
            # measured sim rate) whether the units ran out of commands; the next ticks judge by the sim clock
            self.get_logger().warning(f"the planner was held up {gap:.3f} s (wall clock)")
            try:
                cast(VibrationStream, self.stream).check_stall(run["seen"], gap * self.clock_rate.rate())
            except StreamInterrupted as exc:
                self.abort(str(exc), WARN, "HELD_UP")
            return
        now = self.now_s()
        rel = run["seen"] = now - run["t0"]
        # a run has its stream (both set by start)
        end = cast(VibrationStream, self.stream).planned_end if self.state == "running" else \
            cast(VibrationStream, self.stream).rest_at
        if cast(VibrationStream, self.stream).finished and end is not None and rel >= end:
            cancelled = self.state == "stopping"
            if not cancelled and not run.get("confirmed"):
                # the planner's clock ran through the plan, but the robot never said its units moved
                self.abort("the hardware emulator never reported the units vibrating for this goal (its "
                           "vibration/status stayed at rest): nothing was delivered", WARN, "STOPPED_EARLY")
                return
            self.state = "idle"
            self._finish("CANCELED" if cancelled else "SUCCEEDED",
                         "cancelled: ramped out" if cancelled else "the vibration ran as planned")
            self._report(OK, "idle")
            return
        if wall >= run["next_feedback"]:
            run["next_feedback"] = wall + FEEDBACK_PERIOD_S
            self._feedback(run)
        correct = False
        if self.loop is not None and self.state == "running":
            duration = run["settings"]["duration_s"]
            step = self.loop.step(rel, duration - run["settings"]["ramp_s"] if duration > 0 else None)
            if step.action == "abort":
                self._abort_delivery(step.reason)
                return
            correct = step.action == "correct"
        stream = cast(VibrationStream, self.stream)
        if not correct and (stream.finished or now < run["next_send"]):
            return
        run["next_send"] = now + run["settings"]["window_period_s"]
        try:  # a correction goes at once, after the final window too (it replaces that from its splice)
            window = stream.correction_window(rel) if correct else stream.next_window(rel)
        except StreamInterrupted as exc:
            self.abort(str(exc), WARN, "HELD_UP")
            return
        if window is not None:
            self.publish(window)

    def publish(self, window) -> None:
        started = time.perf_counter()
        self.pub.publish(joint_trajectory.encode_joint_trajectory(
            VIB_NAMES, self.run["t0"], window.times, window.position, window.velocity, window.acceleration))
        self.diagnostics.values.update(windows_sent=str(cast(VibrationStream, self.stream).windows_sent),
                                       last_window_points=str(len(window.times)),
                                       last_window_encode_ms=f"{(time.perf_counter() - started) * 1e3:.2f}")


    def shutdown(self) -> None:
        """A vibration still running ramps out (its goal ends SHUTDOWN): the units never keep a stale stream."""
        if self.run is not None and self.state == "running":
            self._stop_streaming()
        self._finish("SHUTDOWN", "the vibration planner is shutting down: the vibration ramps out")


def loop_figures(run: dict) -> tuple[int, float]:
    """The corrections the closed loop of ``run`` sent and how far they moved the demands (0, 0.0 without a
    loop; SineController.correction)."""
    loop = run.get("loop")
    return (0, 0.0) if loop is None else (int(loop.controller.updates), loop.controller.correction)


def main(args=None) -> int:
    """Run the vibration planner node until SIGINT / SIGTERM; returns the exit code (2: it cannot start)."""
    return run_node(VibrationPlannerNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
