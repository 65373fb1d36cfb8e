"""Emulator vibration buffer: interpolation, replacement, limits, watchdog and stop ramps (issue 5)."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration import VibrationLimitError
from stewart_vibration.emulation.trajectory import build_trajectory
from stewart_vibration.emulation.vibration_buffer import VibrationBuffer

VIB = [f"vib_{i}" for i in range(1, 7)]
GAINS = np.array([0.9, -0.7, 0.95, 0.88, -0.83, 0.94])
F, A = 35.0, 60e-6


RAMP = 0.1  # s, quintic smoothstep ramp-in from rest at t = 0


def signal(t, amp=A, gains=GAINS, ramp=True):
    """(position, velocity) [n, 6] of amp * e(t) * gains * sin(2 pi F t), e a smooth ramp-in from rest."""
    t = np.asarray(t, dtype=float)
    w = 2 * np.pi * F
    if ramp:
        x = np.clip(t / RAMP, 0.0, 1.0)
        env, denv = x**3 * (10 - 15 * x + 6 * x * x), 30 * x**2 * (1 - x) ** 2 / RAMP
    else:
        env, denv = np.ones_like(t), np.zeros_like(t)
    pos = amp * (env * np.sin(w * t))[:, None] * gains
    vel = amp * (denv * np.sin(w * t) + env * w * np.cos(w * t))[:, None] * gains
    return pos, vel


def window(start, t0, t1, dt=1e-3, amp=A, gains=GAINS, ramp=True):
    """Samples of ``signal`` on [t0, t1] (times relative to ``start``)."""
    t = np.arange(t0, t1 + dt / 2, dt)
    return build_trajectory(VIB, VIB, start, t, *signal(t, amp, gains, ramp))


@pytest.fixture
def buffer(robot):
    return VibrationBuffer(robot.vibration_unit, watchdog_s=0.5, ramp_s=0.05)


def test_cubic_interpolation_reproduces_the_sine(buffer):
    buffer.add(window(10.0, 0.0, 0.6), now=9.9)
    t = np.linspace(10.01, 10.39, 777)  # before the watchdog (last receipt 9.9 + 0.5 s)
    pos, vel, acc = buffer.sample(t)
    w = 2 * np.pi * F
    exact, exact_vel = signal(t - 10.0)
    assert np.abs(pos - exact).max() < 1e-4 * A  # cubic Hermite at 28 samples/period
    assert np.abs(vel - exact_vel).max() < 1e-2 * A * w
    steady = t > 10.0 + RAMP
    assert np.abs(acc[steady] + w * w * exact[steady]).max() < 0.1 * A * w * w  # cubic: piecewise-linear accel


def test_new_window_replaces_from_its_first_sample(buffer):
    t0 = 100.0  # a stamp of 0 would mean "now"
    buffer.add(window(t0, 0.0, 0.6), now=t0)
    buffer.add(window(t0, 0.3, 0.9, amp=A / 2), now=t0 + 0.25)
    assert buffer.end == pytest.approx(t0 + 0.9)
    p_old, _, _ = buffer.sample([t0 + 0.2])
    p_new, _, _ = buffer.sample([t0 + 0.4])
    w = 2 * np.pi * F
    assert np.allclose(p_old[0], A * np.sin(w * 0.2) * GAINS, atol=1e-9)
    assert np.allclose(p_new[0], A / 2 * np.sin(w * 0.4) * GAINS, atol=1e-9)


def test_amplitude_and_acceleration_limits_name_the_leg(robot, buffer):
    too_big = robot.vibration_unit.amplitude_max * 1.5
    gains = np.array([0.1, 0.1, 1.0, 0.1, 0.1, 0.1])
    with pytest.raises(VibrationLimitError, match="vib_3") as info:
        buffer.add(window(0.0, 0.0, 0.2, amp=too_big, gains=gains), now=0.0)
    assert info.value.limit_name == "amplitude_max" and info.value.leg == 3
    # acceleration: 90 um at 120 Hz is 51 m/s^2 peak, far above 1 g
    w = 2 * np.pi * 120
    t = np.arange(0, 0.1, 2e-4)
    pos = 90e-6 * np.sin(w * t)[:, None] * np.eye(6)[4]
    vel = 90e-6 * w * np.cos(w * t)[:, None] * np.eye(6)[4]
    with pytest.raises(VibrationLimitError, match="vib_5") as info:
        buffer.add(build_trajectory(VIB, VIB, 0.0, t, pos, vel), now=0.0)
    assert info.value.limit_name == "acceleration_max"


def ramp_checks(buffer, t_from, t_to):
    t = np.arange(t_from, t_to, 1e-4)
    pos, vel, acc = buffer.sample(t)
    step = np.abs(np.diff(pos, axis=0)).max()
    dt = t[1] - t[0]
    assert np.allclose(np.gradient(pos, dt, axis=0)[2:-2], vel[2:-2], atol=0.02 * A * 2 * np.pi * F)
    assert step < 2 * np.pi * F * A * 1e-4 * 1.5  # never more than the sine's own slope per sample
    return t, pos


def test_watchdog_ramps_to_zero_within_100_ms_and_latches(buffer):
    buffer.add(window(0.0, 0.0, 2.0), now=0.0)  # long window, then silence
    t, pos = ramp_checks(buffer, 0.0, 0.7)
    silent_since = 0.5  # watchdog time after the last receipt
    assert np.abs(pos[t < silent_since]).max() > 0.5 * A
    assert np.abs(pos[t >= silent_since + 0.1]).max() == 0.0
    assert buffer.latched and "watchdog" in buffer.ramp_reason
    with pytest.raises(VibrationLimitError, match="start from rest"):
        buffer.add(window(0.0, 0.807, 1.4), now=0.75)  # mid-sine restart refused
    with pytest.raises(VibrationLimitError, match="start from rest"):
        buffer.add(window(0.8, 0.0, 0.5, ramp=False), now=0.75)  # a zero crossing is not rest: full speed there
    t = np.arange(0.0, 0.5, 1e-3)
    env, denv = np.minimum(t / 0.2, 1.0) ** 2, np.where(t < 0.2, 2 * t / 0.04, 0.0)
    w = 2 * np.pi * F
    pos = (A * env * np.sin(w * t))[:, None] * GAINS
    vel = (A * (denv * np.sin(w * t) + env * w * np.cos(w * t)))[:, None] * GAINS
    buffer.add(build_trajectory(VIB, VIB, 0.8, t, pos, vel), now=0.75)  # a ramp-in from rest: accepted
    assert not buffer.latched


def test_commands_running_out_ramp_to_zero(buffer):
    buffer.add(window(0.0, 0.0, 0.3), now=0.0)
    t, pos = ramp_checks(buffer, 0.0, 0.5)
    assert np.abs(pos[t >= 0.3 + 0.1]).max() == 0.0
    assert "ran out" in buffer.ramp_reason


def test_a_late_first_window_is_refused_not_started_mid_ramp(buffer):
    with pytest.raises(VibrationLimitError, match="after its first sample"):
        buffer.add(window(100.0, 0.0, 0.6), now=100.05)  # half-way up the ramp-in when it arrives
    buffer.add(window(100.0, 0.0, 0.6), now=99.95)  # on time: accepted
    assert buffer.end == pytest.approx(100.6)


def test_stop_ramps_from_now(buffer):
    buffer.add(window(0.0, 0.0, 1.0), now=0.0)
    buffer.sample(np.arange(0, 0.2, 1e-3))
    buffer.stop(0.2, "emergency stop")
    t, pos = ramp_checks(buffer, 0.2, 0.4)
    assert np.abs(pos[t >= 0.2 + 0.05]).max() == 0.0
