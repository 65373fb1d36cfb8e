"""One calibration pose's measurement: the tracker frames and strut readings of a settle window, averaged
(pure numpy), refused when the tracker did not deliver fresh frames (frozen, stalled or absent)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import CalibrationError
from ..kinematics.rotations import rotation_from_quaternion

MIN_FRAMES = 5


@dataclass(frozen=True)
class PoseMeasurement:
    """The averages of one window: tracker position (3,) m and rotation (3, 3), strut readings (6,) m, how
    many tracker frames went in, and the legs' load cells (6,) N (NaN for a leg without readings)."""

    position: np.ndarray
    rotation: np.ndarray
    readings: np.ndarray
    frames: int
    loads: np.ndarray = field(default_factory=lambda: np.full(6, np.nan))


def mean_rotation(rotations: np.ndarray) -> np.ndarray:
    """The chordal mean of rotations (N, 3, 3): the rotation nearest their arithmetic mean."""
    u, _, vt = np.linalg.svd(rotations.mean(axis=0))
    return u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt


def average_window(stamps: np.ndarray, positions: np.ndarray, quaternions: np.ndarray, readings: np.ndarray,
                   window: tuple[float, float], expected_rate_hz: float, noisy: bool = True,
                   loads: np.ndarray | None = None) -> PoseMeasurement:
    """Average the tracker frames stamped inside ``window`` (s), the strut readings (M, 6) m taken in it and
    the load cells' readings (M, 6) N of the same states (None: not measured; a leg with a gap averages to NaN).

    Raises:
        CalibrationError: TRACKER_FROZEN when fewer than half the frames ``expected_rate_hz`` promises (and
            fewer than MIN_FRAMES) arrived, when their stamps repeat, or, for a ``noisy`` tracker (one declared
            with noise), when every frame is the same to the last bit; BAD_DATA without strut readings.
    """
    start, end = window
    inside = (stamps >= start) & (stamps <= end)
    stamps, positions, quaternions = stamps[inside], positions[inside], quaternions[inside]
    expected = (end - start) * expected_rate_hz
    if len(stamps) < max(MIN_FRAMES, 0.5 * expected):
        raise CalibrationError("TRACKER_FROZEN", f"the tracker delivered {len(stamps)} frames in the "
                                                 f"{end - start:.2f} s window at t = {start:.2f} s ({expected:.0f} "
                                                 "expected)")
    if len(np.unique(stamps)) < len(stamps) or (noisy and (np.ptp(positions, axis=0) == 0).all()):
        raise CalibrationError("TRACKER_FROZEN", f"the tracker repeated one frame in the window at t = "
                                                 f"{start:.2f} s (stamps or values unchanged): it is frozen")
    if readings.ndim != 2 or readings.shape[0] == 0:
        raise CalibrationError("BAD_DATA", f"no strut readings in the window at t = {start:.2f} s")
    cells = np.full(6, np.nan) if loads is None or len(loads) != len(readings) else np.asarray(loads).mean(axis=0)
    return PoseMeasurement(positions.mean(axis=0), mean_rotation(rotation_from_quaternion(quaternions)),
                           readings.mean(axis=0), int(len(stamps)), cells)
