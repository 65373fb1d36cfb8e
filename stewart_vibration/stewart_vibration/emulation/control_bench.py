"""An in-process bench for the vibration control (no ROS): the controller's pure cores drive the emulated robot
(``HardwareEmulator``, the realistic plant included) and see only its sensors (the units' displacement sensors,
the platform IMU); the bench reads the plant's truth (the platform's true pose) to judge what was delivered.
For benchmarks and tests of the loop's mathematics on the real physics; the nodes run the same cores over DDS.

Modes: "open_loop" (the decomposition's legs: the planner without an identification), "feedforward" (the
demands H^-1 y* of an identification), "closed_loop" (the feed-forward corrected from the IMU by the planner's
own loop, ``vibration.closed_loop``). A vibration is started, streamed and corrected as the planner does it
(``vibration.settings.start_check`` with the planner's default settings), so the bench measures the controller
that runs.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import cast

import numpy as np

from ..errors import InvalidInputError, StewartError
from ..kinematics import inverse_kinematics
from ..kinematics.rotations import rotation_from_quaternion, rotation_from_rpy, so3_exp, so3_log
from ..motion.profiles import minimum_jerk, minimum_jerk_duration
from ..robot import LEG_NAMES, VIB_NAMES, Robot
from ..vibration.closed_loop import (
    DEFAULT_IMU_AVERAGE_S,
    DEFAULT_IMU_SILENCE_S,
    LoopStep,
    closed_loop_for,
)
from ..vibration.compensation import target_motion
from ..vibration.demand_schedule import DemandSchedule
from ..vibration.identification_run import excitation_plan, identify_units, step_samples
from ..vibration.settings import default_settings, start_check
from ..vibration.sine_control import DEFAULT_LOOP_GAIN, DeliveredSine, delivered_figures
from ..vibration.sine_fit import fit_sinusoid
from ..vibration.unit_identification import VibrationIdentification
from .emulator import HardwareEmulator

STATE_PERIOD_S = 0.002  # the emulator's sensor period (500 Hz)
UNIT_SENSOR_LATENCY_S = 0.0005  # a unit's sensor reports its 2 kHz firmware's last reading


def move_to(emu: HardwareEmulator, robot: Robot, pose, settle_s: float = 0.5) -> None:
    """A minimum-jerk move from where the struts read now to ``pose`` (``robot``: the controller's model) at
    10 mm/s (0.5 s at least), then ``settle_s`` at rest."""
    start, goal = np.asarray(emu.joint_state()[1][:6], float), inverse_kinematics(robot, pose)
    duration = minimum_jerk_duration(start, goal, 0.01, 0.5)
    times = np.linspace(duration / 40, duration, 40)
    emu.command_struts(LEG_NAMES, 0.0, times, *minimum_jerk(start, goal, duration, times))
    end = emu.time + duration + settle_s
    while emu.time < end:
        emu.advance(STATE_PERIOD_S)


def run_excitation(emu: HardwareEmulator, steps, amplitude_m: float, lead_s: float = 0.1,
                   truth: bool = False) -> dict:
    """Run the identification ``steps`` (vibration.identification_run), each step's window commanded just
    before it starts; every state period records: times (s from t0), the unit sensors (N, 6), the IMU's
    specific force and rate (N, 3) each; with ``truth``, for judging only, the units' true displacements
    (N, 6) and the platform's true pose (N, 6) too."""
    t0 = emu.time + lead_s
    keys = ["times", "units", "accel", "gyro"] + (["true_units", "true_pose"] if truth else [])
    rec: dict[str, list] = {key: [] for key in keys}

    def record():
        emu.advance(STATE_PERIOD_S)
        imu = emu.imu_sample()
        rec["times"].append(emu.time - t0)
        rec["units"].append(emu.joint_state()[1][6:])
        rec["accel"].append(imu.linear_acceleration)
        rec["gyro"].append(imu.angular_velocity)
        if truth:
            rec["true_units"].append(emu.true_joint_state()[1][6:])
            rec["true_pose"].append(emu.platform_pose())

    for step in steps:
        while emu.time < t0 + step.start - 0.05:
            record()
        grid = np.arange(0.0, step.duration + 1e-9, 0.001)
        x, v, a = step_samples(step, amplitude_m, grid + step.start)
        emu.command_vibration(VIB_NAMES, t0 + step.start, grid, x, v, a)
    while emu.time < t0 + steps[-1].end + 0.02:
        record()
    return {key: np.asarray(value) for key, value in rec.items()}


def tracked_rotation(emu: HardwareEmulator, seconds: float = 0.5) -> np.ndarray:
    """The platform's orientation (3, 3) in the base frame from the external tracker's frames over ``seconds``
    at rest (their mean rotation): the IMU's axes as they are, not as the drawing's FK puts them."""
    quaternions = []
    end = emu.time + seconds
    while emu.time < end:
        emu.advance(STATE_PERIOD_S)
        quaternions += [frame.quaternion for frame in emu.tracker_frames()]
    rotations = rotation_from_quaternion(np.asarray(quaternions))
    mean = so3_log(rotations @ rotations[0].T).mean(axis=0)
    return so3_exp(mean) @ rotations[0]


def identify(emu: HardwareEmulator, robot: Robot, pose, frequencies, amplitude_m: float = 20e-6,
             min_measure_s: float = 0.6, rotation=None) -> VibrationIdentification:
    """The identification run at ``pose`` (the robot must be at rest there), from the sensors only;
    ``rotation``: the platform's measured orientation (``tracked_rotation``), default the pose's."""
    steps = excitation_plan(frequencies, min_measure_s=min_measure_s)
    rec = run_excitation(emu, steps, amplitude_m)
    return identify_units(steps, amplitude_m, pose, rec["times"], rec["units"], rec["accel"], rec["gyro"],
                          gravity=robot.gravity, accel_average_s=DEFAULT_IMU_AVERAGE_S,
                          unit_sensor_latency_s=UNIT_SENSOR_LATENCY_S, rotation=rotation)


@dataclass
class BenchRun:
    """What one vibration delivered: per update period (``times`` s from t0) the truth's figures against
    the target; the loop's verdicts; the outcome ("completed" or the abort's reason)."""

    mode: str
    times: list = field(default_factory=list)
    truth: list[DeliveredSine] = field(default_factory=list)
    verdicts: list[str] = field(default_factory=list)
    outcome: str = "completed"
    frequency_error: float = 0.0
    leg_phase_spread_deg: float = float("nan")  # the true legs' phases against the plan's, max - min (deg)
    demand_correction: float = 0.0  # how far the closed loop moved the demands (SineController.correction)


def true_motion(times, poses, frequency: float, nominal_rotation) -> np.ndarray:
    """The platform's true 6-DOF motion (6,) complex [dp; dphi] (base frame) over ``poses`` (N, 6)."""
    rotations = rotation_from_rpy(np.asarray(poses)[:, 3:])
    dphi = so3_log(rotations @ np.asarray(nominal_rotation).T)
    fit = fit_sinusoid(times, np.column_stack([np.asarray(poses)[:, :3], dphi]), frequency)
    return fit.complex_amplitude


def vibrate(emu: HardwareEmulator, robot: Robot, pose, direction, mode: str, acceleration_g: float = 0.3,
            frequency: float = 35.0, duration_s: float = 4.0, ramp_s: float = 0.2,
            identification: VibrationIdentification | None = None, gain: float = DEFAULT_LOOP_GAIN, disturb=None,
            measured_rotation=None) -> BenchRun:
    """One vibration along ``direction`` (base frame) at ``pose`` in ``mode`` (module docstring), started,
    streamed and corrected as the planner does it: ``settings.start_check`` with the planner's default
    streaming, and in "closed_loop" the planner's own loop (``closed_loop.closed_loop_for``: its measurement,
    its travel margin through the identified unit responses, its aborts), stepped every state period.
    ``disturb``: called as disturb(emu, t) every state period (t s from t0), to change the plant mid-vibration;
    ``measured_rotation``: the platform's orientation the loop takes the IMU's axes at (``tracked_rotation``;
    default the pose's). The truth is judged about the platform's true orientation."""
    if mode not in ("open_loop", "feedforward", "closed_loop"):
        raise InvalidInputError(f"mode must be open_loop, feedforward or closed_loop, got {mode!r}")
    if mode != "open_loop" and identification is None:
        raise InvalidInputError(f"{mode} needs the units' identification (the planner's feed-forward)")
    s = {**default_settings(robot), "direction": [float(v) for v in direction], "frame": "base",
         "acceleration_g": acceleration_g, "frequency_hz": frequency, "duration_s": duration_s, "ramp_s": ramp_s}
    started = start_check(robot, pose, s, identification=None if mode == "open_loop" else identification,
                          closed_loop=mode == "closed_loop")
    plan, stream = started.plan, started.stream
    target = target_motion(plan)
    rotation = rotation_from_rpy(np.asarray(pose)[3:])  # the nominal orientation: the truth's reference
    imu_axes = rotation if measured_rotation is None else np.asarray(measured_rotation, float)
    loop = None
    if mode == "closed_loop":
        loop = closed_loop_for(robot, plan, cast(DemandSchedule, started.schedule), stream,
                               cast(VibrationIdentification, identification), imu_axes, ramp_s, gain,
                               DEFAULT_IMU_AVERAGE_S, DEFAULT_IMU_SILENCE_S)
    run = BenchRun(mode)
    t0 = emu.time + started.start_lead

    def send(window) -> bool:
        """Send ``window`` (None: nothing); False (with the outcome set) when the robot refuses it."""
        if window is None:
            return True
        try:
            emu.command_vibration(VIB_NAMES, t0, window.times, window.position, window.velocity,
                                  window.acceleration)
        except StewartError as exc:  # e.g. the units' travel protection ramped them out: the robot stopped it
            report, _ = emu.vibration_report()
            run.outcome = f"the robot refused the next window ({report.state}: {report.reason}): {exc}"
            return False
        return True

    send(started.first)
    period_s = s["window_period_s"]
    next_send, span = -started.start_lead + period_s, 4 / frequency
    times, poses, legs = [], [], []
    next_judge = 0.0
    while emu.time < t0 + duration_s + 0.05:
        emu.advance(STATE_PERIOD_S)
        now = emu.time - t0
        if disturb is not None:
            disturb(emu, now)
        report, _ = emu.vibration_report()  # what the robot's vibration/status says
        if report.state in ("stopped", "estopped") or emu.vibration.stop_start is not None:
            run.outcome = f"the robot ramped the vibration out: {emu.vibration.stop_reason or report.reason}"
            break
        if now >= 0:
            times.append(now)
            poses.append(emu.platform_pose())
            true_lengths = emu.true_joint_state()[1]
            legs.append(true_lengths[:6] + true_lengths[6:])  # strut and unit in series: the leg's vibration
        if ramp_s + span < now <= duration_s - ramp_s and now >= next_judge:  # the truth, for judging only
            next_judge = now + span
            t = np.asarray(times)
            recent = t > now - span
            run.times.append(now)
            run.truth.append(delivered_figures(true_motion(t[recent], np.asarray(poses)[recent], frequency,
                                                           rotation), target, 0.1))
        correct = False
        if loop is not None:
            imu = emu.imu_sample()
            reason = loop.add_imu(now, imu.linear_acceleration, imu.angular_velocity)
            step = LoopStep("abort", reason) if reason else loop.step(now, duration_s - ramp_s)
            if step.control is not None:
                run.verdicts.append(step.control.verdict)
            if step.action == "abort":
                run.outcome = step.reason
                send(stream.stop_window(now))
                break
            correct = step.action == "correct"
        if correct or (now >= next_send and not stream.finished):
            next_send = now + period_s
            if not send(stream.correction_window(now) if correct else stream.next_window(now)):
                break
    if loop is not None:
        run.demand_correction = loop.controller.correction
    steady = (np.asarray(times) > ramp_s) & (np.asarray(times) < duration_s - ramp_s)
    if steady.sum() > 100:
        z = np.asarray(poses)[steady, :3] @ plan.direction
        run.frequency_error = _frequency_error(np.asarray(times)[steady], z, frequency)
        last = steady & (np.asarray(times) > np.asarray(times)[steady][-1] - span)
        run.leg_phase_spread_deg = leg_phase_spread(np.asarray(times)[last], np.asarray(legs)[last], frequency, plan)
    return run


def leg_phase_spread(times, legs, frequency: float, plan) -> float:
    """max - min over the legs of the phase (deg) of each leg's vibration in ``legs`` (N, 6) m against the plan's
    leg vibration (its gains' signs and phase): 0 when the six legs keep the planned phases."""
    measured = fit_sinusoid(times, legs - legs.mean(axis=0), frequency).complex_amplitude
    planned = plan.leg_amplitudes * np.exp(1j * plan.leg_phases)
    offsets = np.angle(measured / planned)
    offsets = np.angle(np.exp(1j * (offsets - np.angle(np.exp(1j * offsets).mean()))))  # about their mean
    return float(np.degrees(offsets.max() - offsets.min()))


def _frequency_error(times, signal, frequency: float) -> float:
    """Relative error of the signal's frequency against ``frequency``, from the drift of its phase."""
    halves = np.array_split(np.arange(times.size), 2)
    phases = [np.angle(fit_sinusoid(times[h], signal[h], frequency).complex_amplitude) for h in halves]
    drift = np.angle(np.exp(1j * (phases[1] - phases[0])))
    span = times[halves[1]].mean() - times[halves[0]].mean()
    return float(drift / (2 * np.pi * span) / frequency)
