"""One identification run as the planner streams it (pure): the stepped-sine windows to send when their time
comes, the sensors' samples collected by their stamps, and the identification at the end.

Times are s from the run's t0. The unit sensors (legs/joint_states vib_*) and the IMU arrive as separate
streams stamped with the same state times; they are joined by stamp.
"""

from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError
from .feasibility import check_command_limits
from .identification_run import THERAPY_BAND_HZ, ExcitationStep, excitation_plan, identify_units, step_samples
from .unit_identification import VibrationIdentification

SAMPLE_PERIOD_S = 0.001  # the windows' grid
MAX_RUN_S = 180.0  # the longest run (s): ~30 frequencies of the therapy band (six steps of ~0.9 s each)
DEFAULT_AMPLITUDE_M = 20e-6  # each unit's demand: a fifth of a 100 um travel
MIN_MEASURE_S = 0.6  # each step's measured part (s): >= 12 periods at 20 Hz


def identification_steps(frequencies_hz: tuple, amplitude_m: float, unit) -> tuple[list[ExcitationStep], float]:
    """The steps of a run at ``frequencies_hz`` (() = THERAPY_BAND_HZ) with each unit's demand ``amplitude_m``
    (0 = DEFAULT_AMPLITUDE_M), checked against the VibrationUnit ``unit``'s limits: (steps, amplitude m).
    InvalidInputError for a malformed request, VibrationLimitError for one past a unit's limit."""
    amplitude = amplitude_m or DEFAULT_AMPLITUDE_M
    limit = 0.5 * unit.amplitude_max  # a resonance may double the demand
    if not 0 < amplitude <= limit:
        raise InvalidInputError(f"amplitude_m {amplitude!r} must be in (0, {limit:g}] m (half the units' travel: "
                                "a resonance may double it)")
    outside = [f for f in frequencies_hz if not unit.frequency_min <= f <= unit.frequency_max]
    if outside:
        raise InvalidInputError(f"frequencies_hz {outside} outside the units' band [{unit.frequency_min:g}, "
                                f"{unit.frequency_max:g}] Hz")
    steps = excitation_plan(frequencies_hz or THERAPY_BAND_HZ, min_measure_s=MIN_MEASURE_S)
    if steps[-1].end > MAX_RUN_S:
        raise InvalidInputError(f"the run would take {steps[-1].end:.0f} s, more than {MAX_RUN_S:.0f} s: fewer or "
                                "higher frequencies_hz (each step measures at least 12 periods)")
    for step in steps[-6:]:  # the highest frequency: the largest velocity and acceleration
        grid = np.arange(0.0, step.duration, SAMPLE_PERIOD_S)
        check_command_limits(unit, grid, *step_samples(step, amplitude, grid + step.start))
    return steps, amplitude


class IdentificationSession:
    """The run of ``steps`` (identification_run.excitation_plan) at ``pose`` with ``amplitude_m``."""

    def __init__(self, steps: list[ExcitationStep], amplitude_m: float, pose):
        self.steps, self.amplitude_m = list(steps), float(amplitude_m)
        self.pose = np.asarray(pose, dtype=float)
        self.sent = 0  # windows sent
        self.units: dict[int, np.ndarray] = {}  # stamp (us) -> vib_1..6 (m)
        self.imu: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # stamp (us) -> (specific force, rate)

    @property
    def end(self) -> float:
        """When the last step is back at rest (s from t0)."""
        return self.steps[-1].end

    def due_windows(self, now: float, lead_s: float):
        """The windows whose step starts within ``lead_s`` of ``now``: (start s from t0, times from that start,
        position, velocity, acceleration (N, 6)) each, in order; each once."""
        while self.sent < len(self.steps) and self.steps[self.sent].start <= now + lead_s:
            step = self.steps[self.sent]
            grid = np.arange(0.0, step.duration + 1e-9, SAMPLE_PERIOD_S)
            yield (step.start, grid, *step_samples(step, self.amplitude_m, grid + step.start))
            self.sent += 1

    def progress(self, now: float) -> tuple[int, int, int, float]:
        """(step 1-based (0 before the first), steps, unit 1..6 (0 between steps), frequency Hz) at ``now``."""
        for k, step in enumerate(self.steps):
            if step.start <= now <= step.end:
                return k + 1, len(self.steps), step.unit + 1, step.frequency
        done = sum(step.end < now for step in self.steps)
        return done, len(self.steps), 0, 0.0

    def add_units(self, t: float, units) -> None:
        """The units' sensor readings (6,) m at ``t``."""
        self.units[int(round(t * 1e6))] = np.asarray(units, dtype=float)

    def add_imu(self, t: float, accel, gyro) -> None:
        """The IMU's specific force and rate (3,) each at ``t``."""
        self.imu[int(round(t * 1e6))] = (np.asarray(accel, dtype=float), np.asarray(gyro, dtype=float))

    def identification(self, gravity, accel_average_s: float, unit_sensor_latency_s: float,
                       provenance: dict) -> VibrationIdentification:
        """The identification from the samples both streams hold (identification_run.identify_units)."""
        stamps = sorted(set(self.units) & set(self.imu))
        times = np.array(stamps) * 1e-6
        units = np.array([self.units[s] for s in stamps]).reshape(-1, 6)
        accel = np.array([self.imu[s][0] for s in stamps]).reshape(-1, 3)
        gyro = np.array([self.imu[s][1] for s in stamps]).reshape(-1, 3)
        return identify_units(self.steps, self.amplitude_m, self.pose, times, units, accel, gyro, gravity=gravity,
                              accel_average_s=accel_average_s, unit_sensor_latency_s=unit_sensor_latency_s,
                              provenance=provenance)
