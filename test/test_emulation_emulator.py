"""The emulated robot without ROS: the strut servos track a 35 Hz, 0.3 g vibration at the
paper's pose within the main scenario's bounds, the reported axial forces equal the Newton-Euler model of
the simulated motion, and the e-stop / reset rules hold."""

from __future__ import annotations

import numpy as np
import pytest
from emulator_runs import PERIOD, move_and_settle, start_tibia_vibration

from stewart_vibration import inverse_kinematics
from stewart_vibration.analysis.fits import direction_error_deg, fit_sinusoid, line_vibration
from stewart_vibration.dynamics.newton_euler import leg_forces
from stewart_vibration.emulation.emulator import HardwareEmulator
from stewart_vibration.errors import ActuatorLimitError, StrokeLimitError
from stewart_vibration.motion.profiles import minimum_jerk, minimum_jerk_duration
from stewart_vibration.paper import paper_pose
from stewart_vibration.robot import LEG_NAMES, VIB_NAMES
from stewart_vibration.sim.mjcf import load_simulation_settings
from stewart_vibration.vibration import decompose_vibration
from stewart_vibration.vibration.streaming import StreamSettings, VibrationStream


@pytest.fixture(scope="module")
def vibrated(robot):
    """Move to the paper's pose, vibrate 2 s (35 Hz, 0.3 g along the tibia axis); record every state."""
    emu = HardwareEmulator(robot, load_simulation_settings(timestep=1 / 2000))
    pose = paper_pose(robot)
    settled = move_and_settle(emu, robot, pose)
    plan, t0 = start_tibia_vibration(emu, robot, pose)
    rows, states, raw = [], [], []
    while emu.time < t0 + 2.2:
        emu.advance(PERIOD)
        _, pos, vel, eff = emu.joint_state()
        sim = emu.sim
        rows.append((emu.time, pos, vel, eff[:6], sim.platform_pose(), sim.platform_twist()))
        raw.append((sim.data.qpos.copy(), sim.data.qvel.copy(), emu.forces.copy()))
        states.append(emu.vibration_report()[0].state)
    return {"emu": emu, "plan": plan, "t0": t0, "settled": settled, "pose": pose, "rows": rows, "states": states,
            "raw": raw[len(raw) // 4:len(raw) // 4 + 200]}


def columns(rows, k):
    return np.array([r[k] for r in rows])


def test_servo_holds_the_pose_after_a_move(vibrated):
    err = vibrated["settled"] - vibrated["pose"]
    assert np.abs(err[:3]).max() < 1e-6 and np.degrees(np.abs(err[3:]).max()) < 1e-4


def test_servo_tracks_the_vibration_within_the_scenario_bounds(vibrated):
    rows, plan, t0 = vibrated["rows"], vibrated["plan"], vibrated["t0"]
    t = columns(rows, 0)
    steady = (t > t0 + 0.4) & (t < t0 + 1.6)
    poses = columns(rows, 4)[steady]
    line = line_vibration(t[steady], poses[:, :3], 35.0)
    assert direction_error_deg(line.direction, plan.direction) < 0.1  # scenario bound 0.5 deg
    assert abs(line.amplitude / plan.amplitude - 1) < 0.005  # scenario bound 2 %
    pos = columns(rows, 1)[steady]
    hinge = pos[:, :6] + pos[:, 6:]
    commanded = pos[:, 6:]  # vib_i as commanded (the emulator reports the command it follows)
    fit, ref = fit_sinusoid(t[steady], hinge, 35.0), fit_sinusoid(t[steady], commanded, 35.0)
    assert np.abs(fit.amplitude / ref.amplitude - 1).max() < 0.005
    assert np.degrees(np.abs(np.angle(fit.complex_amplitude / ref.complex_amplitude))).max() < 0.5


def test_reported_forces_are_what_moves_the_simulated_robot(robot, vibrated):
    """At each reported state, MuJoCo's own equations with the reported axial forces give an acceleration
    whose Newton-Euler forces are the reported ones (the force a load cell reads is the one that acts)."""
    emu = vibrated["emu"]
    drive = emu.drive
    worst = 0.0
    for qpos, qvel, forces in vibrated["raw"]:
        lengths, rates = qpos[drive.slide_q], qvel[drive.slide_v]
        pose, twist, accel, gap = emu.sim.evaluate(qpos, qvel, forces + drive.kp * lengths + drive.kv * rates)
        model = leg_forces(robot, pose, twist, accel)
        worst = max(worst, np.abs(model - forces).max())
        assert gap < 1e-6
    assert worst < 2e-4  # N, of forces ~5 N with ~3 N of vibration (measured 3.5e-5: U-joint spin, soft loops)


def test_status_walks_through_the_vibration(vibrated):
    states = vibrated["states"]
    order = [s for i, s in enumerate(states) if i == 0 or states[i - 1] != s]
    assert order == ["pending", "ramping_in", "running", "ramping_out", "idle"]


def test_estop_ramps_the_units_out_within_100_ms_and_reset_needs_it(robot):
    emu = HardwareEmulator(robot, load_simulation_settings(timestep=1 / 2000))
    with pytest.raises(ActuatorLimitError, match="no emergency stop is latched"):
        emu.reset()
    plan = decompose_vibration(robot, robot.home_pose, [0.0, 0.0, 1.0], acceleration_g=0.3, frequency=35.0)
    t0 = 0.2
    window = VibrationStream(robot, plan, StreamSettings(duration=3.0)).next_window(-t0)
    emu.command_vibration(VIB_NAMES, t0, window.times, window.position, window.velocity, window.acceleration)
    while emu.time < 1.0:
        emu.advance(PERIOD)
    emu.emergency_stop()
    stopped_at = emu.time
    vib = []
    while emu.time < stopped_at + 0.3:
        emu.advance(PERIOD)
        vib.append((emu.time, emu.joint_state()[1][6:]))
    assert all(np.abs(v).max() == 0.0 for t, v in vib if t >= stopped_at + 0.1)
    assert emu.vibration_report()[0].state == "estopped"
    with pytest.raises(ActuatorLimitError, match="emergency stop"):
        emu.command_vibration(VIB_NAMES, emu.time + 0.5, window.times, window.position, window.velocity)
    assert emu.reset() > 0 and not emu.estopped


def dense_commanded(emu, t0, t1):
    """The strut command the emulator will follow, sampled every 0.5 ms: (positions, velocities, accelerations)."""
    t = np.arange(t0, t1, 5e-4)
    return t, *emu.struts.sample(t)


@pytest.mark.parametrize("stamp_offset,outcome", [(-5.0, "stale_trajectory"), (-3.0, "strut_velocity_max"),
                                                  (-0.05, "accepted"), (0.0, "accepted"), (2.0, "accepted")])
def test_past_stamped_trajectory_departs_from_now_or_is_refused(robot, stamp_offset, outcome):
    """A legal 5 mm move over 4 s whose stamp lies in the past (it used to jump 5 mm at 0.88 m/s):
    the part already past is dropped and the motion departs from the commanded state now -- refused when
    that would break a limit, otherwise within every limit."""
    emu = HardwareEmulator(robot, load_simulation_settings(timestep=1 / 2000))
    for _ in range(3000):  # 6 s: a stamp 5 s in the past is a real time
        emu.advance(PERIOD)
    home = inverse_kinematics(robot, robot.home_pose)
    times = np.linspace(0.1, 4.0, 40)
    goal = home + 0.005
    pos, vel, acc = minimum_jerk(home, goal, 4.0, times)
    lim = robot.limits
    if outcome != "accepted":
        with pytest.raises((ActuatorLimitError, StrokeLimitError)) as err:
            emu.command_struts(LEG_NAMES, emu.time + stamp_offset, times, pos, vel, acc)
        assert err.value.limit_name == outcome and "ago" in str(err.value), str(err.value)
        return
    emu.command_struts(LEG_NAMES, emu.time + stamp_offset, times, pos, vel, acc)
    t, p, v, a = dense_commanded(emu, emu.time, emu.time + 6.5)
    assert np.abs(v).max() <= lim.strut_velocity_max * (1 + 1e-6)
    assert np.abs(a).max() <= lim.strut_acceleration_max * (1 + 1e-6)
    assert np.abs(p[-1] - goal).max() < 1e-12
    assert np.abs(p[0] - home).max() < 1e-9  # no jump at the departure


def test_position_only_and_far_future_trajectories(robot):
    emu = HardwareEmulator(robot, load_simulation_settings(timestep=1 / 2000))
    home = inverse_kinematics(robot, robot.home_pose)
    with pytest.raises(ActuatorLimitError, match="max_start_delay_s"):
        emu.command_struts(LEG_NAMES, emu.time + 1000.0, [1.0], [home + 0.001])
    # positions only: cubic segments with finite-difference velocities, zero at the ends: no velocity step
    times = np.linspace(1.0, 10.0, 10)
    emu.command_struts(LEG_NAMES, 0.0, times, home + 0.004 * (times[:, None] - 1.0) / 9.0)
    t, p, v, a = dense_commanded(emu, emu.time, emu.time + 11.0)
    assert np.abs(np.diff(v, axis=0)).max() < robot.limits.strut_acceleration_max * 5e-4 * 1.01
    assert np.abs(a).max() <= robot.limits.strut_acceleration_max
    with pytest.raises(ActuatorLimitError, match="strut_acceleration_max"):  # 1 mm in 0.2 s, from rest
        emu.command_struts(LEG_NAMES, 0.0, [0.2], [home + 0.001], [np.zeros(6)])


def test_estop_during_a_move_brings_the_struts_to_rest_within_the_acceleration_limit(robot):
    """No joint beyond its limits, an e-stop included. Struts moving near full speed are brought to
    rest by a controlled stop (holding the position at once, the old e-stop, stepped the velocity by ~18 mm/s
    in one physics step); the simulated struts follow it without a step, and the force estimator's mirror
    of the strut command makes the same stop."""
    from stewart_vibration.emulation.strut_trajectory import build_trajectory
    from stewart_vibration.emulation.vibration_status import EMERGENCY_STOP
    from stewart_vibration.estimation import ForceEstimator

    lim = robot.limits
    emu = HardwareEmulator(robot, load_simulation_settings(timestep=1 / 2000))
    home = inverse_kinematics(robot, robot.home_pose)
    goal = home + np.array([0.01, -0.01, 0.01, -0.01, 0.01, -0.01])
    duration = minimum_jerk_duration(home, goal, 0.9 * lim.strut_velocity_max, 0.5)
    times = np.linspace(duration / 40, duration, 40)
    pos, vel, acc = minimum_jerk(home, goal, duration, times)
    emu.command_struts(LEG_NAMES, 0.0, times, pos, vel, acc)
    estimator = ForceEstimator(robot)
    zeros = np.zeros((1, 6))
    estimator.estimate([0.0], home[None, :], zeros, zeros, zeros)
    estimator.command_struts(build_trajectory(LEG_NAMES, LEG_NAMES, 0.0, times, pos, vel, acc), now=0.0)
    while emu.time < 0.45 * duration:
        emu.advance(PERIOD)
    stop_time = emu.time
    speed_before = np.abs(emu.struts.sample([stop_time])[1]).max()
    assert speed_before > 0.8 * lim.strut_velocity_max  # a real stop from near full speed
    emu.emergency_stop()
    t, p, v, a = dense_commanded(emu, stop_time - 0.01, stop_time + 3.0)
    assert np.abs(a).max() <= lim.strut_acceleration_max * (1 + 1e-6)
    assert np.abs(np.diff(v, axis=0)).max() <= lim.strut_acceleration_max * 5e-4 * (1 + 1e-6)  # no velocity step
    assert np.abs(v[-1]).max() == 0.0 and np.all((p >= lim.stroke_min) & (p <= lim.stroke_max))
    travel = np.abs(p[-1] - emu.struts.sample([stop_time])[0][0]).max()
    assert travel <= speed_before**2 / lim.strut_acceleration_max  # within twice the ideal braking distance
    measured = []  # the simulated struts
    while emu.time < stop_time + 1.0:
        emu.advance(PERIOD)
        measured.append(emu.joint_state()[2][:6])
    assert np.abs(np.diff(measured, axis=0)).max() <= 5 * lim.strut_acceleration_max * PERIOD
    estimator.apply_ramp(stop_time, EMERGENCY_STOP, "emergency_stop")
    estimator.apply_ramp(stop_time, EMERGENCY_STOP, "emergency_stop")  # the status repeats at 10 Hz: mirrored once
    mirrored = estimator.struts.sample(t)
    for ours, theirs in zip(mirrored, (p, v, a)):
        assert np.abs(ours - theirs).max() < 1e-12


@pytest.mark.parametrize("plant", ["", "realistic"])
def test_a_robot_built_again_within_a_run_goes_on_from_the_run_clock(robot, plant):
    """start_time (a lifecycle cleanup + configure within a run): the same move and vibration, commanded
    relative to now, give the same motion shifted in time -- nothing in the robot counts from 0."""
    from stewart_vibration.emulation.plant import load_plant_option

    settings = load_simulation_settings(timestep=1 / 2000)
    start, goal = inverse_kinematics(robot, robot.home_pose), inverse_kinematics(robot, paper_pose(robot))
    duration = minimum_jerk_duration(start, goal, 0.01, 0.5)
    times = np.linspace(duration / 40, duration, 40)
    runs = []
    built = load_plant_option(plant, robot, 1)
    for t_start in (0.0, 123.456):
        emu = HardwareEmulator(robot, settings, plant=built, start_time=t_start)
        assert emu.time == t_start
        emu.command_struts(LEG_NAMES, 0.0, times, *minimum_jerk(start, goal, duration, times))  # 0 = now
        rows = []
        while emu.time < t_start + duration + 0.1:
            emu.advance(PERIOD)
            rows.append(emu.joint_state()[1])
        _, t0 = start_tibia_vibration(emu, robot, paper_pose(robot), duration_s=0.6)
        assert t0 == pytest.approx(emu.time + 0.3)
        while emu.time < t0 + 0.35:  # ramped in (0.2 s), before the ramp-out
            emu.advance(PERIOD)
            rows.append(emu.joint_state()[1])
        assert emu.vibration_report()[0].state == "running" and emu.fault is None
        runs.append(np.array(rows))
    assert runs[0].shape == runs[1].shape
    assert np.abs(runs[1][:, 6:]).max() > 1e-5  # the units did vibrate
    if built is None:
        assert np.abs(runs[1] - runs[0]).max() < 1e-9
    else:  # the times' rounding may flip an encoder count at its boundary, and the servo then acts a count apart
        step = built.sensors.encoder_quantization_m
        assert np.abs(runs[1][:, :6] - runs[0][:, :6]).max() <= 1.01 * step
        assert np.abs(runs[1][:, 6:] - runs[0][:, 6:]).max() < 1e-3 * np.abs(runs[0][:, 6:]).max()
