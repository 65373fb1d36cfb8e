"""The identification run of the vibration units (pure): a stepped-sine excitation, one unit and one frequency
at a time, each step ramped in and out at rest; and the identification from what the robot's own sensors
recorded meanwhile (each unit's displacement sensor, the platform IMU), never from the plant's truth.

Times are s from the run's start stamp t0 (the windows' common stamp); amplitudes m of unit demand.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError
from ..kinematics.rotations import rotation_from_rpy
from .frequency_response import platform_motion_response, sine_response
from .unit_identification import VibrationIdentification
from .waveform import sinusoid

THERAPY_BAND_HZ = (20.0, 25.0, 30.0, 35.0, 40.0, 45.0, 50.0, 55.0, 60.0)


@dataclass(frozen=True)
class ExcitationStep:
    """Unit ``unit`` (0..5) driven at ``frequency`` Hz from ``start`` (s from t0): a ramp of ``ramp_s``, a
    settling time ``settle_s``, ``measure_s`` of whole periods measured, a ramp out."""

    unit: int
    frequency: float
    start: float
    ramp_s: float
    settle_s: float
    measure_s: float

    @property
    def duration(self) -> float:
        """The step's length (s): both ramps, the settling and the measured time."""
        return 2.0 * self.ramp_s + self.settle_s + self.measure_s

    @property
    def end(self) -> float:
        """When the step is back at rest (s from t0)."""
        return self.start + self.duration

    @property
    def measured(self) -> tuple[float, float]:
        """The measured interval (s from t0): after the ramp and the settling, before the ramp out."""
        first = self.start + self.ramp_s + self.settle_s
        return first, first + self.measure_s


def excitation_plan(frequencies=THERAPY_BAND_HZ, units=range(6), ramp_s: float = 0.05, settle_s: float = 0.15,
                    min_measure_s: float = 0.4, min_periods: int = 12, gap_s: float = 0.02) -> list[ExcitationStep]:
    """The steps, frequency by frequency and unit by unit within each; each measures whole periods, at least
    ``min_periods`` and ``min_measure_s``; ``gap_s`` at rest between steps."""
    freqs = [float(f) for f in frequencies]
    if not freqs or any(not math.isfinite(f) or f <= 0 for f in freqs) or sorted(set(freqs)) != freqs:
        raise InvalidInputError(f"frequencies must be positive, distinct and increasing, got {freqs}")
    steps, start = [], 0.0
    for f in freqs:
        periods = max(min_periods, math.ceil(min_measure_s * f - 1e-9))
        for unit in units:
            step = ExcitationStep(int(unit), f, start, ramp_s, settle_s, periods / f)
            steps.append(step)
            start = step.end + gap_s
    return steps


def step_samples(step: ExcitationStep, amplitude_m: float, times) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The demand of ``step`` at ``times`` (N,) s from t0: position, velocity, acceleration (N, 6), its unit's
    column a ramped sine of ``amplitude_m`` (m), the others zero."""
    t = np.asarray(times, dtype=float)
    x, v, a = sinusoid(t - step.start, amplitude_m, step.frequency, 0.0, step.duration, step.ramp_s)
    out = [np.zeros((t.size, 6)) for _ in range(3)]
    for column, values in zip(out, (x, v, a)):
        column[:, step.unit] = values
    return out[0], out[1], out[2]


def identify_units(steps: list[ExcitationStep], amplitude_m: float, pose, times, unit_readings, accel, gyro,
                   gravity=(0.0, 0.0, 0.0), accel_average_s: float = 0.0, unit_sensor_latency_s: float = 0.0,
                   blocks: int = 4, provenance: dict | None = None, rotation=None) -> VibrationIdentification:
    """The identification from the recorded sensors of a run of ``steps`` at ``pose`` (6,).

    Args:
        times: sample times (N,) s from t0, the sensors' stamps.
        unit_readings: each unit's displacement sensor (N, 6) m.
        accel, gyro: the platform IMU's specific force (N, 3) m/s^2 and rate (N, 3) rad/s, platform frame.
        gravity: (3,) m/s^2 in the base frame (the robot's ``gravity``).
        accel_average_s: the interval the accelerometer averages over before each sample (its sample period
            for an integrate-and-dump device; ``platform_motion_response``).
        rotation: the platform's orientation (3, 3) in the base frame, as measured (e.g. by the external
            tracker); default: the pose's (the drawing's FK, off by the geometry's errors).
        unit_sensor_latency_s: how old a unit sensor's reading is when reported (its firmware reports the
            reading of its last control cycle): the unit's response is its displacement's, this delay removed.

    Raises:
        InvalidInputError: a step's measured interval is not covered by the samples, or ``sine_response``'s.
    """
    t = np.asarray(times, dtype=float)
    readings = np.column_stack([np.asarray(unit_readings, float), np.asarray(accel, float),
                                np.asarray(gyro, float)])
    rotation = rotation_from_rpy(np.asarray(pose, float)[3:]) if rotation is None else np.asarray(rotation, float)
    freqs = sorted({s.frequency for s in steps})
    n = len(freqs)
    unit_h, unit_c, unit_u = (np.full((n, 6), np.nan, dtype=complex) for _ in range(3))
    plat_h, plat_c, plat_u = (np.full((n, 6, 6), np.nan, dtype=complex) for _ in range(3))
    for step in steps:
        first, last = step.measured
        inside = (t >= first - 1e-9) & (t <= last + 1e-9)
        if inside.sum() < 8 or t[inside][0] > first + 0.01 or t[inside][-1] < last - 0.01:
            raise InvalidInputError(f"unit {step.unit + 1} at {step.frequency:g} Hz: the record does not cover "
                                    f"its measured interval {first:.3f}-{last:.3f} s")
        demand = step_samples(step, amplitude_m, t[inside])[0][:, step.unit]
        r = sine_response(t[inside], demand, readings[inside], step.frequency, blocks)
        k, j = freqs.index(step.frequency), step.unit
        w = 2.0 * np.pi * step.frequency
        latency = np.exp(1j * w * unit_sensor_latency_s)  # the reading lags the displacement by the latency
        unit_h[k, j], unit_c[k, j], unit_u[k, j] = r.response[j] * latency, r.coherence[j], r.uncertainty[j]
        plat_h[k, :, j] = platform_motion_response(r.response[6:9], r.response[9:12], step.frequency, rotation,
                                                   gravity, accel_average_s)
        plat_c[k, :, j] = r.coherence[6:12]  # per IMU axis (platform frame)
        spread = np.abs(rotation) ** 2  # independent errors through the rotation
        plat_u[k, :3, j] = np.sqrt(spread @ (r.uncertainty[6:9] / w**2) ** 2)
        plat_u[k, 3:, j] = np.sqrt(spread @ (r.uncertainty[9:12] / w) ** 2)
    if np.isnan(unit_h).any():
        raise InvalidInputError("the steps do not drive every unit at every frequency")
    return VibrationIdentification(
        pose=np.asarray(pose, float), frequencies=np.asarray(freqs), amplitude_m=float(amplitude_m),
        unit_response=unit_h, unit_coherence=unit_c.real, unit_uncertainty=unit_u.real, platform_response=plat_h,
        platform_coherence=plat_c.real, platform_uncertainty=plat_u.real, provenance=dict(provenance or {}))
