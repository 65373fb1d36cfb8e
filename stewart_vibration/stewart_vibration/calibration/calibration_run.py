"""One calibration run's settings and measurements (pure numpy): what the kinematics node's calibrate action
asks for, checked, and the sensor streams it keeps while a pose's window is open."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError
from .identification import MIN_POSES
from .pose_average import PoseMeasurement, average_window

MAX_POSES = 200
DEFAULTS = {"poses": 60, "settle_s": 0.5, "window_s": 1.0, "reach_m": 0.02, "tilt_deg": 15.0}
LIMITS = {"settle_s": (0.0, 10.0), "window_s": (0.1, 10.0), "reach_m": (0.001, 0.1), "tilt_deg": (0.0, 45.0)}


@dataclass(frozen=True)
class CalibrationSettings:
    """poses; settle_s and window_s (s) at each; reach_m (m) and tilt_rad (rad) per axis about home; seed of the
    pose plan; plan_only; output_path ("" = a dated name)."""

    poses: int
    settle_s: float
    window_s: float
    reach_m: float
    tilt_rad: float
    seed: int
    plan_only: bool
    output_path: str


def calibration_settings(poses: int, settle_s: float, window_s: float, reach_m: float, tilt_deg: float, seed: int,
                         plan_only: bool, output_path: str) -> CalibrationSettings:
    """The settings of a calibrate goal (0 = the default of each number); InvalidInputError naming a bad one."""
    values = {"poses": poses, "settle_s": settle_s, "window_s": window_s, "reach_m": reach_m, "tilt_deg": tilt_deg}
    for name, value in values.items():
        if not math.isfinite(value):
            raise InvalidInputError(f"calibrate: {name} must be finite, got {value}")
        values[name] = value if value != 0 else DEFAULTS[name]
    count = int(values["poses"])
    if not MIN_POSES <= count <= MAX_POSES:
        raise InvalidInputError(f"calibrate: poses {count} outside [{MIN_POSES}, {MAX_POSES}] (7 parameters per leg "
                                "need at least 12 poses)")
    for name, (low, high) in LIMITS.items():
        if not low <= values[name] <= high:
            raise InvalidInputError(f"calibrate: {name} {values[name]:g} outside [{low:g}, {high:g}]")
    return CalibrationSettings(count, float(values["settle_s"]), float(values["window_s"]), float(values["reach_m"]),
                               math.radians(values["tilt_deg"]), int(seed), bool(plan_only), str(output_path))


class WindowRecorder:
    """The tracker frames, strut readings and load cells of one open window (nothing is kept while none is
    open)."""

    def __init__(self):
        self.window: tuple[float, float] | None = None
        self._frames: list[tuple[float, np.ndarray, np.ndarray]] = []
        self._readings: list[np.ndarray] = []
        self._loads: list[np.ndarray] = []

    def open(self, start: float, end: float) -> None:
        """Keep what is stamped in [start, end] (robot clock, s) from now."""
        self.window, self._frames, self._readings, self._loads = (start, end), [], [], []

    def add_frame(self, stamp: float, position, quaternion) -> None:
        """One tracker frame: stamp (s), position (3,) m, quaternion (4,) [x, y, z, w], base frame."""
        if self.window is not None and self.window[0] <= stamp <= self.window[1]:
            self._frames.append((stamp, np.asarray(position, float), np.asarray(quaternion, float)))

    def add_readings(self, stamps: np.ndarray, readings: np.ndarray, loads: np.ndarray | None = None) -> None:
        """Strut readings (M, 6) m (leg_i + vib_i) and load cells (M, 6) N (NaN where not measured) stamped
        ``stamps`` (M,) s."""
        if self.window is not None:
            inside = (stamps >= self.window[0]) & (stamps <= self.window[1])
            if inside.any():
                self._readings.append(readings[inside])
                self._loads.append(np.full((int(inside.sum()), 6), np.nan) if loads is None else loads[inside])

    def measure(self, tracker_rate_hz: float, noisy: bool) -> PoseMeasurement:
        """The window's averages (``average_window``'s refusals) and close it."""
        assert self.window is not None
        window, frames = self.window, self._frames
        readings = np.concatenate(self._readings) if self._readings else np.empty((0, 6))
        loads = np.concatenate(self._loads) if self._loads else np.empty((0, 6))
        self.window = None
        stamps = np.array([f[0] for f in frames])
        positions = np.array([f[1] for f in frames]).reshape(-1, 3)
        quaternions = np.array([f[2] for f in frames]).reshape(-1, 4)
        return average_window(stamps, positions, quaternions, readings, window, tracker_rate_hz, noisy, loads)
