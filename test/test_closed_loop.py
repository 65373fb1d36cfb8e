"""vibration.closed_loop on a linear model of the robot (no MuJoCo): the platform moves by P u(t), P the
kinematic map of units with +-30 % / +-20 deg errors, u(t) the demands in force (blends included); a
noiseless IMU at the platform origin reports it. The loop, on the stream's timing (0.3 s lead, 0.5 s windows),
corrects the nominal plan into the band; a silent or implausible IMU aborts it."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.kinematics.jacobian import jacobian
from stewart_vibration.kinematics.rotations import rotation_from_rpy
from stewart_vibration.paper import paper_pose
from stewart_vibration.vibration.closed_loop import ClosedLoop
from stewart_vibration.vibration.compensation import target_motion
from stewart_vibration.vibration.decompose import decompose_vibration
from stewart_vibration.vibration.demand_schedule import DemandSchedule
from stewart_vibration.vibration.leg_demands import decomposition_demands
from stewart_vibration.vibration.sine_control import SineController, SineControlLimits, delivered_figures
from stewart_vibration.vibration.streaming import StreamSettings, VibrationStream

F, DT, RAMP = 35.0, 0.002, 0.2
UNITS = np.array([1.3, 0.7, 1.2, 0.8, 1.25, 0.75]) * np.exp(1j * np.radians([20, -20, 12, -15, -8, 18]))


def setup(robot):
    pose = paper_pose(robot)
    plan = decompose_vibration(robot, pose, [0.0, 0.0, 1.0], acceleration_g=0.3, frequency=F)
    nominal = np.linalg.inv(jacobian(robot, pose))
    schedule = DemandSchedule(decomposition_demands(plan), F)
    stream = VibrationStream(robot, plan, StreamSettings(duration=None), demands=schedule)
    controller = SineController(nominal, target_motion(plan), initial_demand=decomposition_demands(plan))
    rotation = rotation_from_rpy(pose[3:])
    loop = ClosedLoop(controller, schedule, stream, rotation, robot.gravity, RAMP,
                      accel_average_s=0.0)  # the synthetic IMU samples instantaneously
    return plan, nominal @ np.diag(UNITS), schedule, stream, loop, rotation


def imu_of(plant, schedule, rotation, gravity, t):
    """Specific force and rate (platform frame) of the linear robot at ``t`` (the demands in force then)."""
    y = plant @ schedule.demand_at(t)
    w = 2 * np.pi * F
    z = np.exp(1j * w * t)
    accel = np.imag(-w * w * y[:3] * z) - gravity
    rate = np.imag(1j * w * y[3:] * z)
    return rotation.T @ accel, rotation.T @ rate


def test_the_loop_corrects_the_nominal_plan_into_the_band(robot):
    plan, plant, schedule, stream, loop, rotation = setup(robot)
    before = delivered_figures(plant @ schedule.current, target_motion(plan), 0.1)
    assert before.direction_error_deg > 2.0  # the unit errors tilt the vibration
    stream.next_window(-0.3)
    corrections, next_send = 0, 0.2
    for k in range(int(20.0 / DT)):  # ~0.5 s per correction (lead, blend, measurement): 40 of them
        t = k * DT
        loop.add_imu(t, *imu_of(plant, schedule, rotation, robot.gravity, t))
        step = loop.step(t, None)
        assert step.action != "abort", step.reason
        if step.action == "correct":
            corrections += 1
            stream.next_window(t)
            next_send = t + 0.5
        elif t >= next_send:
            stream.next_window(t)
            next_send = t + 0.5
    after = delivered_figures(plant @ schedule.current, target_motion(plan), 0.1)
    assert after.direction_error_deg < 0.1 and abs(after.amplitude_error) < 0.005 and after.off_axis_ratio < 0.005
    assert 20 <= corrections <= 45


def test_a_silent_or_implausible_imu_aborts_with_the_reason(robot):
    plan, plant, schedule, stream, loop, rotation = setup(robot)
    stream.next_window(-0.3)
    steps = []
    for k in range(int(1.0 / DT)):
        t = k * DT
        if t < 0.5:  # the IMU stops at 0.5 s
            loop.add_imu(t, *imu_of(plant, schedule, rotation, robot.gravity, t))
        steps.append(loop.step(t, None))
        if steps[-1].action == "abort":
            break
    assert steps[-1].action == "abort" and "IMU went silent" in steps[-1].reason
    assert 0.6 <= t <= 0.61
    assert "non-finite" in loop.add_imu(1.0, [np.nan, 0, 0], [0, 0, 0])
    assert "beyond what this vibration can make" in loop.add_imu(1.0, [0, 0, 200.0], [0, 0, 0])


@pytest.mark.parametrize("rate_hz, aborts", [(50.0, True), (40.0, True), (120.0, False)])
def test_an_imu_too_sparse_to_measure_aborts_like_a_silent_one(robot, rate_hz, aborts):
    """Samples keep coming, but 4 periods at 35 Hz (0.114 s) hold fewer than the 8 a measurement needs below
    ~70 Hz: the loop cannot see the vibration, and says so once the measurement is silence_s (0.1 s) late;
    at 120 Hz (13 per measurement) it measures and corrects."""
    plan, plant, schedule, stream, loop, rotation = setup(robot)
    stream.next_window(-0.3)
    period = round(1.0 / rate_hz / DT)
    actions = []
    for k in range(int(1.0 / DT)):
        t = k * DT
        if k % period == 0:
            loop.add_imu(t, *imu_of(plant, schedule, rotation, robot.gravity, t))
        step = loop.step(t, None)
        actions.append(step.action)
        if step.action == "abort":
            break
    if aborts:
        assert "too sparse to measure" in step.reason and "8 needed" in step.reason, step.reason
        # due at the ramp's end plus one measurement (0.314 s), aborted silence_s later
        assert RAMP + 4 / F + 0.1 < t <= RAMP + 4 / F + 0.1 + 2 * DT
    else:
        assert "abort" not in actions and "correct" in actions


@pytest.mark.parametrize("steady_until", [0.5])
def test_nothing_is_corrected_after_the_steady_part(robot, steady_until):
    plan, plant, schedule, stream, loop, rotation = setup(robot)
    stream.next_window(-0.3)
    for k in range(int(1.0 / DT)):
        t = k * DT
        loop.add_imu(t, *imu_of(plant, schedule, rotation, robot.gravity, t))
        step = loop.step(t, steady_until)
        if t > steady_until:
            assert step.action == "wait"


@pytest.mark.parametrize("change, why", [(1.5 * np.eye(6), "+3.5 dB"),
                                         (np.diag([0.3, 1, 1, 1, 1, 1]), "vibration direction")])
def test_a_vibration_sent_whole_is_corrected_until_its_ramp_out_then_only_judged(robot, change, why):
    """A 2.35 s vibration sent whole in its first window, planned with its identified plant's feed-forward:
    the loop still corrects it (each correction goes out in a window that replaces the rest) while a
    correction can splice before the ramp-out (until 1.85 s, with lead_s 0.3 s and the ramp-out from 2.15 s);
    after that every abort limit is judged -- the direction and off-axis ones too, however few corrections
    were made, since none can follow -- on samples taken once the last correction settled, but nothing is
    corrected. The platform's response changes at 1.9 s: 1.5x louder, or unit 1 at 30 % of its gain."""
    plan, plant, schedule, _, _, rotation = setup(robot)
    feedforward = np.linalg.solve(plant, target_motion(plan))
    schedule = DemandSchedule(feedforward, F)
    finite = VibrationStream(robot, plan, StreamSettings(duration=2.35), demands=schedule)
    controller = SineController(plant, target_motion(plan), initial_demand=feedforward)
    loop = ClosedLoop(controller, schedule, finite, rotation, robot.gravity, RAMP, accel_average_s=0.0)
    assert finite.next_window(-0.3).final  # sent whole
    steps = []
    for k in range(int(2.15 / DT)):
        t = k * DT
        plant_now = plant @ change if t >= 1.9 else plant
        loop.add_imu(t, *imu_of(plant_now, schedule, rotation, robot.gravity, t))
        steps.append((t, loop.step(t, 2.15)))
        if steps[-1][1].action == "correct":
            assert finite.correction_window(t) is not None
        if steps[-1][1].action == "abort":
            break
    corrections = [t for t, step in steps if step.action == "correct"]
    assert 3 <= len(corrections) < SineControlLimits().converge_updates and max(corrections) < 1.85
    assert finite.correction_window(1.9) is None
    t_abort, abort = steps[-1]
    assert abort.action == "abort" and why in abort.reason and abort.control is None and 1.9 < t_abort <= 2.15
