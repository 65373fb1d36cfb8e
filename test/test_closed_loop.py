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
from stewart_vibration.vibration.sine_control import SineController, delivered_figures
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


def test_after_the_last_window_the_limits_are_still_judged_but_nothing_is_corrected(robot):
    plan, plant, schedule, stream, loop, rotation = setup(robot)
    finite = VibrationStream(robot, plan, StreamSettings(duration=1.0), demands=schedule)
    loop.stream = finite
    assert finite.next_window(-0.3).final  # a short vibration is sent whole: nothing left to correct
    loud = 1.5 * np.linalg.solve(plant, target_motion(plan))  # what makes the platform move 1.5x the target
    schedule.changes[0] = (-np.inf, loud)
    steps = []
    for k in range(int(0.7 / DT)):
        t = k * DT
        loop.add_imu(t, *imu_of(plant, schedule, rotation, robot.gravity, t))
        steps.append(loop.step(t, 0.8))
        if steps[-1].action == "abort":
            break
    assert steps[-1].action == "abort" and "+3.5 dB" in steps[-1].reason
    assert all(s.action in ("wait", "abort") for s in steps) and len(schedule.changes) == 1
