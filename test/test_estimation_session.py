"""The estimator's per-run state without ROS: a batch gives the per-message forces sample for
sample, the commanded accelerations come from the emulator's own buffer (including its e-stop ramp),
and the modelled forces match what the emulator applied."""

from __future__ import annotations

import numpy as np
import pytest
from test_delivered_units import FollowsDemands

from stewart_vibration.emulation.emulator import HardwareEmulator
from stewart_vibration.emulation.strut_trajectory import build_trajectory
from stewart_vibration.estimation import ForceEstimator
from stewart_vibration.estimation.delivered_units import FIT_WINDOW_S
from stewart_vibration.kinematics import inverse_kinematics
from stewart_vibration.robot import VIB_NAMES
from stewart_vibration.sim.mjcf import load_simulation_settings
from stewart_vibration.vibration import decompose_vibration
from stewart_vibration.vibration.streaming import StreamSettings, VibrationStream


@pytest.fixture(scope="module")
def run(robot):
    """A 1.2 s vibration at home with an e-stop at 0.9 s; states every 2 ms and the window sent."""
    emu = HardwareEmulator(robot, load_simulation_settings(timestep=1 / 2000))
    plan = decompose_vibration(robot, robot.home_pose, [0.0, 0.0, 1.0], acceleration_g=0.3, frequency=35.0)
    t0 = 0.2
    window = VibrationStream(robot, plan, StreamSettings(duration=1.2)).next_window(-t0)
    traj = build_trajectory(VIB_NAMES, VIB_NAMES, t0, window.times, window.position, window.velocity,
                            window.acceleration)
    emu.command_vibration(VIB_NAMES, t0, window.times, window.position, window.velocity, window.acceleration)
    states = []
    estop = None
    while emu.time < 1.4:
        emu.advance(0.002)
        if estop is None and emu.time >= 0.9:
            emu.emergency_stop()
            estop = emu.time
        _, pos, vel, eff = emu.joint_state()
        states.append((emu.time, pos, vel, eff[:6]))
    return {"traj": traj, "states": states, "estop": estop, "report": emu.vibration_report()[0]}


def arrays(states):
    t = np.array([s[0] for s in states])
    pos, vel, eff = (np.array([s[k] for s in states]) for k in (1, 2, 3))
    return t, pos[:, :6], pos[:, 6:], vel[:, :6], vel[:, 6:], eff


def estimator(robot, run):
    est = ForceEstimator(robot)
    est.command_vibration(run["traj"], now=0.0)
    report = run["report"]
    est.apply_ramp(report.ramp_start, report.ramp_reason, report.ramp_cause)  # as the emulator reports the e-stop
    return est


def test_batch_equals_one_by_one(robot, run):
    t, struts, vib, strut_rates, vib_rates, eff = arrays(run["states"])
    whole = estimator(robot, run).estimate(t, struts, vib, strut_rates, vib_rates, eff)
    single = estimator(robot, run)
    one = [single.estimate(t[i:i + 1], struts[i:i + 1], vib[i:i + 1], strut_rates[i:i + 1], vib_rates[i:i + 1],
                           eff[i:i + 1]) for i in range(len(t))]
    assert whole.ok.all() and all(o.ok.all() for o in one)
    forces = np.concatenate([o.forces for o in one])
    wrench = np.concatenate([o.wrench for o in one])
    assert np.abs(whole.forces - forces).max() < 1e-12 * np.abs(forces).max()  # ~5.5 N: FK converged to 1e-14 m
    assert np.abs(whole.wrench - wrench).max() < 1e-12 * np.abs(forces).max()


def test_model_matches_the_emulator_through_the_estop(robot, run):
    t, struts, vib, strut_rates, vib_rates, eff = arrays(run["states"])
    est = estimator(robot, run).estimate(t, struts, vib, strut_rates, vib_rates, eff)
    vibrating = (t > 0.5) & (t < 0.85)
    amplitude = (eff[vibrating].max(axis=0) - eff[vibrating].min(axis=0)) / 2
    err = np.abs(est.forces - eff)
    assert (np.sqrt((err[vibrating] ** 2).mean(axis=0)) / amplitude).max() < 0.01
    after = t > run["estop"] + 0.1  # units at rest after the e-stop ramp: the model must know they stopped
    assert (err[after].max(axis=0) / amplitude).max() < 0.01
    ignoring = ForceEstimator(robot)  # the old mirror's failure: assumes the vibration went on ...
    ignoring.delivered = FollowsDemands()  # ... and that the legs follow their demands
    ignoring.command_vibration(run["traj"], now=0.0)
    wrong = ignoring.estimate(t, struts, vib, strut_rates, vib_rates, eff)
    assert (np.abs(wrong.forces - eff)[after].max(axis=0) / amplitude).max() > 0.3
    # the same mirror with the legs' response fitted from the sensors sees the units stop within its fit window
    sensing = ForceEstimator(robot)
    sensing.command_vibration(run["traj"], now=0.0)
    seen = sensing.estimate(t, struts, vib, strut_rates, vib_rates, eff)
    later = t > run["estop"] + 0.1 + 2 * FIT_WINDOW_S  # a whole window of units at rest, then its fit
    assert (np.abs(seen.forces - eff)[later].max(axis=0) / amplitude).max() < 0.01


def test_pose_is_where_strut_plus_vibration_unit_puts_the_platform(robot):
    """The leg length is strut + vibration unit: the estimated pose is the pose whose IK gives that sum."""
    target = robot.home_pose + np.array([0.004, -0.003, 0.002, 0.02, -0.01, 0.03])
    lengths = inverse_kinematics(robot, target)
    vib = np.array([80e-6, -80e-6, 40e-6, -40e-6, 20e-6, -20e-6])
    est = ForceEstimator(robot).estimate([0.0], (lengths - vib)[None], vib[None], np.zeros((1, 6)),
                                         np.zeros((1, 6)))
    assert est.ok.all() and np.abs(est.pose[0] - target).max() < 1e-10
    # the same for rates: only the leg's total rate moves the platform (velocity terms of the forces)
    rates, vib_rates = np.full((1, 6), 0.05) * [1, -1, 2, -2, 1, 1], np.full((1, 6), 0.04)
    split = ForceEstimator(robot).estimate([0.0], lengths[None] - vib, vib[None], rates - vib_rates, vib_rates)
    whole = ForceEstimator(robot).estimate([0.0], lengths[None], np.zeros((1, 6)), rates, np.zeros((1, 6)))
    still = ForceEstimator(robot).estimate([0.0], lengths[None], np.zeros((1, 6)), np.zeros((1, 6)),
                                           np.zeros((1, 6)))
    assert np.abs(split.forces - whole.forces).max() < 1e-9
    assert np.abs(whole.forces - still.forces).max() > 1e-3  # the rates do change the forces


@pytest.mark.parametrize("end_speed_steps", [0.5, 2.0])
def test_mirror_takes_a_move_ending_in_motion_as_a_200_hz_emulator_does(robot, end_speed_steps):
    """A move may end moving by at most the velocity step the emulator's physics step allows; the estimator's
    mirror allows what the coarsest emulator (200 Hz physics) allows: the same verdict as that emulator."""
    from stewart_vibration.emulation.strut_trajectory import STEP_SPEED
    from stewart_vibration.errors import StewartError
    from stewart_vibration.robot import LEG_NAMES

    home = inverse_kinematics(robot, robot.home_pose)
    end_speed = end_speed_steps * STEP_SPEED * robot.limits.strut_acceleration_max / 200
    times = np.array([0.5, 1.0])
    pos = np.vstack([home + 0.0005, home + 0.001])
    vel = np.vstack([np.full(6, 0.001), np.full(6, end_speed)])
    emu = HardwareEmulator(robot, load_simulation_settings(timestep=1 / 200))
    mirror = ForceEstimator(robot)
    zeros = np.zeros((1, 6))
    mirror.estimate([0.0], home[None, :], zeros, zeros, zeros)
    verdicts = []
    for command in (lambda: emu.command_struts(LEG_NAMES, 0.0, times, pos, vel),
                    lambda: mirror.command_struts(build_trajectory(LEG_NAMES, LEG_NAMES, 0.0, times, pos, vel),
                                                  now=0.0)):
        try:
            command()
            verdicts.append("taken")
        except StewartError as exc:
            verdicts.append(f"refused: {exc}")
    expected = "taken" if end_speed_steps < 1 else "refused"
    assert [v.split(":")[0] for v in verdicts] == [expected, expected], verdicts  # emulator, mirror


def streamed_windows(robot, t0: float = 1.0, count: int = 5, scale: float = 1.0):
    """The planner's windows of an until-stop vibration sent every 0.5 s from t0 - 0.3 s: [(trajectory with stamp
    t0, the sim time it is sent at)]; ``scale`` multiplies the displacements (and their derivatives)."""
    plan = decompose_vibration(robot, robot.home_pose, [0.0, 0.0, 1.0], acceleration_g=0.3, frequency=35.0)
    stream = VibrationStream(robot, plan, StreamSettings(duration=None))
    out = []
    for k in range(count):
        now = 0.5 * k - 0.3
        w = stream.next_window(now)
        out.append((build_trajectory(VIB_NAMES, VIB_NAMES, t0, w.times, scale * w.position, scale * w.velocity,
                                     scale * w.acceleration), t0 + now))
    return out


def test_a_restarted_estimator_takes_the_first_window_mid_vibration_as_its_history(robot):
    """An estimator (re)started during a vibration: its empty mirror cannot splice the planner's next window (it
    starts mid-vibration, the old failure: refused, and every later one with it). It takes that window as its
    history instead (the emulator accepted it) and splices the next ones as the emulator does: from the adopted
    window on, the mirror commands what the emulator's own buffer, fed every window, commands."""
    from stewart_vibration.emulation.vibration_buffer import VibrationBuffer
    from stewart_vibration.errors import VibrationLimitError

    windows = streamed_windows(robot)
    emulator = VibrationBuffer(robot.vibration_unit, max_lookahead_s=30.0)  # the emulator's model, every window
    for traj, sent in windows:
        emulator.add(traj, sent)
    fresh_buffer = VibrationBuffer(robot.vibration_unit, max_lookahead_s=np.inf)
    with pytest.raises(VibrationLimitError, match="discontinuous splice"):
        fresh_buffer.add(*windows[2])  # what a fresh mirror did before
    restarted = ForceEstimator(robot)
    taken = [restarted.command_vibration(traj, now=sent) for traj, sent in windows[2:]]
    assert taken == [True, False, False]  # adopted, then spliced
    first = windows[2][0].start + windows[2][0].times[0]
    times = np.linspace(first, windows[-1][0].end + 0.3, 4000)
    for mine, theirs in zip(restarted.vibration.sample(times), emulator.sample(times), strict=True):
        assert np.abs(mine - theirs).max() <= 1e-9 * np.abs(theirs).max()


def test_only_a_fresh_mirror_adopts_and_never_past_the_limits(robot):
    """Adoption is for a mirror that has taken no window yet: one that has keeps refusing a discontinuous window as
    the emulator does; and an adopted window is still checked against the unit's limits."""
    from stewart_vibration.errors import VibrationLimitError

    windows = streamed_windows(robot, count=6)
    running = ForceEstimator(robot)
    assert running.command_vibration(*windows[0]) is False
    with pytest.raises(VibrationLimitError, match="discontinuous splice"):  # windows 1-4 were missed: the first
        running.command_vibration(*windows[5])  # one's ramp-out (from t0 + 2 s) has begun where this one starts
    too_big = streamed_windows(robot, scale=20.0)
    with pytest.raises(VibrationLimitError) as info:
        ForceEstimator(robot).command_vibration(*too_big[2])
    assert info.value.limit_name != "splice"
