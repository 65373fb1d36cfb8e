"""The kinematics node's calibrate action (stewart_vibration_interfaces/action/Calibrate): a kinematic
calibration run on the robot.

The goal's settings are checked (calibration.calibration_run), the poses planned (calibration.pose_plan: inside
every limit, D-optimal), and the plan's condition number and predicted parameter uncertainty sent as the first
feedback before anything moves. Each pose is reached through the node's own kinematics/move_to_pose action
(the same checks, force guard and outcomes as any reduction move); after ``settle_s`` of the robot's clock the
tracker's frames (platform/tracker_pose, raw) and the strut readings (leg_i + vib_i of the states the node
solves anyway) are averaged over ``window_s`` and published on kinematics/calibration_samples (so the run's MCAP
has them). Then the 42 parameters are identified (calibration.identification) and the calibrated robot file
written (calibration.robot_file), atomically.

Outcomes: SUCCEEDED (with the file), INVALID_ARGUMENT, NOT_READY (no states yet), BUSY (a calibration runs),
the move's own outcome when a move fails (GUARD_STOPPED, EMERGENCY_STOPPED, ...), TIMEOUT (the robot's states
stopped), CALIBRATION_REJECTED (too few or degenerate poses, outliers, a frozen tracker: nothing written),
CANCELED (the running move stops; nothing written), SHUTDOWN.
"""

from __future__ import annotations

import datetime
import time
from pathlib import Path

import numpy as np
from geometry_msgs.msg import PoseStamped
from rclpy.action import ActionClient, ActionServer, CancelResponse, GoalResponse
from rclpy.clock import Clock, ClockType
from rclpy.task import Future

from stewart_vibration_interfaces.action import Calibrate, MoveToPose
from stewart_vibration_interfaces.msg import CalibrationSample

from ..calibration.calibration_run import CalibrationSettings, WindowRecorder, calibration_settings
from ..calibration.geometry_parameters import parameters_of
from ..calibration.identification import CalibrationData, CalibrationResult, identifiability, identify
from ..calibration.measurement_model import TrackerNoise
from ..calibration.pose_average import PoseMeasurement
from ..calibration.pose_plan import plan_calibration_poses
from ..calibration.robot_file import calibrated_tree, dump_robot_file
from ..errors import RefusedError, StewartError
from ..estimation.payload_identification import calibrated_load
from ..install import default_config_dir
from ..kinematics.rotations import (
    pose_to_position_quaternion,
    quaternion_from_rpy,
    rotation_from_rpy,
    rpy_from_rotation,
)
from ..messages.fields import BASE_FRAME
from ..messages.stamped import poses_from_cdr
from ..output_files import writable_output, write_text_whole
from ..safe_yaml import load_yaml
from .message_conversions import time_message
from .move_messages import move_goal
from .outcomes import end_goal, outcome, outcome_name
from .service_calls import GoalAcceptances, send_goal_recovering_async

TRACKER_LATENCY_MARGIN_S = 0.2  # the window's last frames arrive this much after its end (the tracker's latency)
STATE_SILENCE_S = 10.0  # wall seconds without a joint state while waiting: the robot is gone
SERVER_WAIT_S = 10.0  # wall seconds for the node's own move action to be discovered


class CalibrationServer:
    """The calibrate action of ``node`` (a KinematicsNode: its robot, parameters, clock and move action)."""

    def __init__(self, node):
        self.node = node
        self.recorder = WindowRecorder()
        self.running = None  # the calibrate goal handle while one runs
        self.move_handle = None  # its current move goal (ClientGoalHandle)
        self.wait: tuple[Future, float, float] | None = None  # (done, robot-clock deadline s, wall deadline s)
        self.last_state_wall = time.monotonic()
        node.create_subscription(PoseStamped, "platform/tracker_pose", self.on_tracker, 100, raw=True)
        self.sample_pub = node.create_publisher(CalibrationSample, "kinematics/calibration_samples", 100)
        self.move_client = ActionClient(node, MoveToPose, "kinematics/move_to_pose")
        self.move_acceptances = GoalAcceptances(node, "kinematics/move_to_pose")
        node.create_timer(0.05, self.check_wait, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.action = ActionServer(node, Calibrate, "kinematics/calibrate", execute_callback=self.execute,
                                   goal_callback=lambda goal: GoalResponse.ACCEPT, cancel_callback=self.on_cancel)

    # -- sensor input ----------------------------------------------------------------------------
    def on_states(self, stamps: np.ndarray, readings: np.ndarray, loads: np.ndarray | None = None) -> None:
        """Solved joint states: stamps (M,) s, strut readings (M, 6) m (leg_i + vib_i), load cells (M, 6) N."""
        self.last_state_wall = time.monotonic()
        self.recorder.add_readings(stamps, readings, loads)
        self.check_wait()

    def on_tracker(self, data: bytes) -> None:
        batch = poses_from_cdr([data], "tracker pose", as_quaternion=True)
        for error in batch.errors:
            self.node.malformed.refuse("platform/tracker_pose", error)
        for stamp, value in zip(batch.stamps, batch.values, strict=True):
            self.recorder.add_frame(float(stamp), value[:3], value[3:])

    # -- waiting on the robot's clock --------------------------------------------------------------
    def until(self, robot_time: float) -> Future:
        """A Future done with True once a state stamped at or after ``robot_time`` (s) was solved, False when
        the goal is cancelled, the states stop (STATE_SILENCE_S) or the node shuts down."""
        done: Future = Future()
        self.wait = (done, robot_time, time.monotonic())
        self.check_wait()
        return done

    def check_wait(self, ending: bool = False) -> None:
        if self.wait is None or self.wait[0].done():
            return
        done, deadline, _ = self.wait
        state_time = self.node.state_time
        if state_time is not None and state_time >= deadline:
            done.set_result(True)
        elif ending or (self.running is not None and self.running.is_cancel_requested) or \
                time.monotonic() - self.last_state_wall > STATE_SILENCE_S:
            done.set_result(False)

    async def wall_sleep(self, seconds: float) -> None:
        done: Future = Future()
        timer = self.node.create_timer(seconds, lambda: done.done() or done.set_result(True),
                                       clock=Clock(clock_type=ClockType.STEADY_TIME))
        await done
        self.node.destroy_timer(timer)

    async def wait_robot(self, robot_time: float, what: str) -> None:
        if not await self.until(robot_time):
            self.raise_if_cancelled()
            raise RefusedError("TIMEOUT", f"calibrate: no joint states for {STATE_SILENCE_S:g} s while {what} "
                                          "(is the hardware emulator running?)")

    def raise_if_cancelled(self) -> None:
        if self.running is not None and self.running.is_cancel_requested:
            raise RefusedError("CANCELED", "calibrate: cancelled; nothing written")

    # -- the action ----------------------------------------------------------------------------------
    def on_cancel(self, goal_handle) -> CancelResponse:
        """Cancel = the running move stops (its own cancel), the run ends CANCELED and writes nothing."""
        if self.move_handle is not None:
            self.move_handle.cancel_goal_async()
        self.check_wait()
        return CancelResponse.ACCEPT

    async def execute(self, goal_handle):
        g = goal_handle.request
        if self.running is not None:
            goal_handle.abort()
            return Calibrate.Result(outcome=outcome("BUSY", "calibrate: a calibration runs already"))
        self.running = goal_handle
        try:
            settings = calibration_settings(g.poses, g.settle_s, g.window_s, g.reach_m, g.tilt_deg, g.seed,
                                            g.plan_only, g.output_path)
            result = await self.run(goal_handle, settings)
        except StewartError as exc:
            name = exc.outcome
            result = Calibrate.Result(outcome=outcome(name, str(exc)))
        except Exception as exc:  # noqa: BLE001 - a defect ends the goal with its code, never a hung client
            name = "INTERNAL_ERROR"
            result = Calibrate.Result(outcome=outcome(name, f"{type(exc).__name__}: {exc}"))
            self.node.get_logger().error(f"calibrate: {type(exc).__name__}: {exc}")
        finally:
            self.running, self.wait, self.move_handle = None, None, None
            self.recorder.window = None
        name = outcome_name(result.outcome.code)
        if name == "SUCCEEDED":
            self.node.get_logger().info(f"calibrate: {name}: {result.outcome.message}")
        else:  # one severity per call site: rclpy refuses a call site whose severity changes
            self.node.get_logger().warning(f"calibrate: {name}: {result.outcome.message}")
        end_goal(goal_handle, name)
        return result

    def noise(self) -> TrackerNoise:
        param = self.node.get_parameter
        return TrackerNoise(param("tracker_position_noise_m").value,
                            float(np.radians(param("tracker_orientation_noise_deg").value)))

    async def run(self, goal_handle, s: CalibrationSettings) -> Calibrate.Result:
        node = self.node
        if node.pose is None:
            raise RefusedError("NOT_READY", "calibrate: no legs/joint_states received yet (is the hardware emulator "
                                            "running?)")
        output = None if s.plan_only else writable_output(s.output_path or datetime.datetime.now().strftime(
            "robot_calibrated_%Y%m%d_%H%M%S.yaml"), "calibrated robot file", lambda tree: "calibration" in tree)
        rate = float(node.get_parameter("tracker_rate_hz").value)
        noise = self.noise()
        frames = max(int(s.window_s * rate), 1)
        poses = plan_calibration_poses(node.robot, s.poses, frames, noise, s.seed, s.reach_m, s.tilt_rad)
        planned = CalibrationData(poses[:, :3], rotation_from_rpy(poses[:, 3:]), np.zeros((len(poses), 6)),
                                  np.full(len(poses), float(frames)))
        condition, predicted = identifiability(parameters_of(node.robot), planned, noise)
        feedback = Calibrate.Feedback(stage="planned", pose=0, poses=len(poses), condition_number=condition,
                                      predicted_std_max_m=float(predicted.max()))
        goal_handle.publish_feedback(feedback)
        node.get_logger().info(f"calibrate: {len(poses)} poses planned, condition number {condition:.1f}, predicted "
                               f"parameter std up to {predicted.max() * 1e6:.2f} um")
        if s.plan_only:
            return Calibrate.Result(outcome=outcome("SUCCEEDED", f"planned {len(poses)} poses (plan only: nothing "
                                                                 "moved)"), condition_number=condition,
                                    predicted_std_max_m=float(predicted.max()))
        measured: list[PoseMeasurement] = []
        for k, pose in enumerate(poses):
            feedback.stage, feedback.pose = "moving", k + 1
            goal_handle.publish_feedback(feedback)
            await self.move(pose, k + 1)
            settled = node.emulator_now() + s.settle_s
            await self.wait_robot(settled, "settling")
            self.recorder.open(settled, settled + s.window_s)
            feedback.stage = "measuring"
            goal_handle.publish_feedback(feedback)
            await self.wait_robot(settled + s.window_s, "measuring")
            await self.wall_sleep(TRACKER_LATENCY_MARGIN_S)
            self.raise_if_cancelled()
            sample = self.recorder.measure(rate, noise.position_m > 0)
            measured.append(sample)
            self.publish_sample(k + 1, pose, sample, settled + s.window_s, s.window_s)
        feedback.stage = "identifying"
        goal_handle.publish_feedback(feedback)
        data = CalibrationData(np.array([m.position for m in measured]), np.array([m.rotation for m in measured]),
                               np.array([m.readings for m in measured]), np.array([m.frames for m in measured], float))
        fit = identify(node.robot, data, noise)
        load, said = calibrated_load(node.robot, fit, data, np.array([m.loads for m in measured]))
        assert output is not None
        self.write(output, fit, s, rate, noise, float(predicted.max()), load)
        dropped = [d.index + 1 for d in fit.dropped]
        return Calibrate.Result(
            outcome=outcome("SUCCEEDED", f"{int(fit.used.sum())} of {len(poses)} poses used"
                                         f"{f', {len(dropped)} dropped' if dropped else ''}; residual RMS "
                                         f"{_rms(fit) * 1e6:.2f} um, chi2/dof {fit.reduced_chi2:.2f}; {said}; "
                                         f"wrote {output}"),
            path=str(output), poses_used=int(fit.used.sum()), poses_dropped=dropped, residual_rms_m=_rms(fit),
            reduced_chi2=fit.reduced_chi2, condition_number=fit.condition_number,
            predicted_std_max_m=float(predicted.max()), parameter_std_max_m=float(fit.std.max()))

    async def move(self, pose: np.ndarray, index: int) -> None:
        """Reach ``pose`` through kinematics/move_to_pose; RefusedError with the move's outcome if it fails."""
        started = time.monotonic()
        while not self.move_client.server_is_ready():
            if time.monotonic() - started > SERVER_WAIT_S:
                raise RefusedError("NOT_READY", "calibrate: kinematics/move_to_pose is not available")
            await self.wall_sleep(0.1)
        self.raise_if_cancelled()
        handle = await send_goal_recovering_async(self.move_client, move_goal(pose), self.move_acceptances)
        if not handle.accepted:
            raise RefusedError("ROBOT_REFUSED", f"calibrate: the move to pose {index} was not accepted")
        self.move_handle = handle
        if self.running is not None and self.running.is_cancel_requested:
            handle.cancel_goal_async()
        answer = await handle.get_result_async()
        self.move_handle = None
        code = answer.result.outcome
        name = outcome_name(code.code)
        if name != "SUCCEEDED":
            self.raise_if_cancelled()
            raise RefusedError(name, f"calibrate: the move to pose {index} ended {name}: {code.message}")

    def publish_sample(self, index: int, pose: np.ndarray, sample: PoseMeasurement, end: float, window_s: float):
        msg = CalibrationSample(pose=index, tracker_frames=sample.frames, window_s=window_s)
        msg.header.frame_id = BASE_FRAME
        msg.header.stamp = time_message(end)
        position, quaternion = pose_to_position_quaternion(pose)
        _fill_pose(msg.commanded, position, quaternion)
        _fill_pose(msg.tracker, sample.position, _quaternion_of(sample.rotation))
        msg.strut_readings_m = [float(v) for v in sample.readings]
        msg.load_cells_n = [float(v) for v in sample.loads]
        self.sample_pub.publish(msg)

    def write(self, output: Path, fit: CalibrationResult, s: CalibrationSettings, rate: float, noise: TrackerNoise,
              predicted_std_max: float, load: dict | None) -> None:
        """The calibrated robot file at ``output``, written whole or not at all (temporary file + rename)."""
        source = self.node.get_parameter("robot_config").value or str(default_config_dir() / "robot.yaml")
        provenance = {"drawing": str(source), "tracker": {"rate_hz": rate, "position_noise_m": noise.position_m,
                                                          "orientation_noise_deg": float(np.degrees(
                                                              noise.orientation_rad))},
                      "settle_s": s.settle_s, "window_s": s.window_s, "reach_m": s.reach_m,
                      "tilt_deg": round(float(np.degrees(s.tilt_rad)), 6), "seed": s.seed,
                      "predicted_std_max_m": float(f"{predicted_std_max:.3g}")}
        text = dump_robot_file(calibrated_tree(load_yaml(Path(source), "robot config"), fit, provenance, load))
        write_text_whole(output, text)

    def shutdown(self) -> None:
        self.check_wait(ending=True)


def _rms(fit: CalibrationResult) -> float:
    return float(np.sqrt(np.mean(fit.residual_rms_m[fit.used] ** 2)))


def _fill_pose(msg, position, quaternion) -> None:
    msg.position.x, msg.position.y, msg.position.z = (float(v) for v in position)
    msg.orientation.x, msg.orientation.y, msg.orientation.z, msg.orientation.w = (float(v) for v in quaternion)


def _quaternion_of(rotation: np.ndarray) -> np.ndarray:
    """The quaternion [x, y, z, w] of a rotation matrix (3, 3)."""
    return quaternion_from_rpy(rpy_from_rotation(rotation))
