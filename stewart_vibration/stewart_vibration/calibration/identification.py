"""Identify the 42 kinematic parameters from calibration poses (scipy.optimize.least_squares).

The residuals are the strut readings predicted from the tracker's pose minus those measured, whitened by
the tracker's noise (``measurement_model``), so the fit is maximum likelihood and (J^T J)^-1 is the
parameters' covariance; it is scaled up by the reduced chi-square when the residuals exceed the noise
model. A pose whose chi-square (6 degrees of freedom) is beyond ``OUTLIER_CHI2`` is reported and dropped,
one at a time (the worst first), and the fit repeated. Refusals (``CalibrationError``): too few poses, a
set that leaves parameters unidentifiable (named), too many disagreeing poses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import CalibrationError
from ..robot import Robot
from .geometry_parameters import PARAMETER_COUNT, parameter_names, parameters_of
from .measurement_model import TrackerNoise, predicted_readings, whitened, whitening

MIN_POSES = 12  # 7 parameters per leg, one reading per pose and leg: 12 leave room to see an outlier
CONDITION_MAX = 1e5  # of the column-scaled whitened Jacobian: beyond it some parameters are not determined
OUTLIER_CHI2 = 27.86  # chi-square of 6 degrees of freedom with a 1e-4 chance for a pose that fits the model
MAX_DROPPED_FRACTION = 0.2  # more disagreeing poses than this: the data, not a few poses, are wrong


@dataclass(frozen=True)
class CalibrationData:
    """The averaged measurements of K poses: tracker positions (K, 3) m and rotations (K, 3, 3) of the
    platform frame in the base frame, strut readings (K, 6) m (encoder plus unit sensor), and the number of
    tracker frames averaged per pose (K,)."""

    positions: np.ndarray
    rotations: np.ndarray
    readings: np.ndarray
    frames: np.ndarray

    def subset(self, keep: np.ndarray) -> CalibrationData:
        """The poses selected by ``keep`` (a mask or indices)."""
        return CalibrationData(self.positions[keep], self.rotations[keep], self.readings[keep], self.frames[keep])

    @property
    def count(self) -> int:
        """The number of poses K."""
        return int(self.readings.shape[0])


@dataclass(frozen=True)
class DroppedPose:
    """A pose the fit disagreed with: its index, chi-square (6 dof) and strut residual RMS (m)."""

    index: int
    chi2: float
    residual_rms_m: float


@dataclass(frozen=True)
class CalibrationResult:
    """theta (42,) m and its covariance (42, 42) m^2; per pose of the data: used (K,), chi-square (K,) and
    strut residual RMS (K,) m at theta; the poses dropped; the reduced chi-square of the fit (about 1 when
    the noise model holds) and the condition number of its scaled Jacobian."""

    theta: np.ndarray
    covariance: np.ndarray
    used: np.ndarray
    chi2: np.ndarray
    residual_rms_m: np.ndarray
    dropped: tuple[DroppedPose, ...]
    reduced_chi2: float
    condition_number: float

    @property
    def std(self) -> np.ndarray:
        """Standard deviations (42,) m of the parameters."""
        return np.sqrt(np.diag(self.covariance))


def check_data(data: CalibrationData) -> None:
    """CalibrationError BAD_DATA for malformed arrays, TOO_FEW_POSES below ``MIN_POSES``."""
    k = data.readings.shape[0] if data.readings.ndim == 2 else -1
    shapes_ok = (data.readings.shape == (k, 6) and data.positions.shape == (k, 3)
                 and data.rotations.shape == (k, 3, 3) and data.frames.shape == (k,))
    if not shapes_ok:
        raise CalibrationError("BAD_DATA", "calibration data: positions (K, 3), rotations (K, 3, 3), readings "
                                           "(K, 6) and frames (K,) must describe the same K poses")
    arrays = (data.positions, data.rotations, data.readings, data.frames)
    if not all(np.isfinite(a).all() for a in arrays) or (data.frames < 1).any():
        raise CalibrationError("BAD_DATA", "calibration data: a value is not finite or a pose averaged no "
                                           "tracker frame")
    if k < MIN_POSES:
        raise CalibrationError("TOO_FEW_POSES", f"calibration data: {k} poses, at least {MIN_POSES} are needed "
                                                "(7 parameters per leg, and room to see an outlier)")


def _scaled_jacobian(theta: np.ndarray, data: CalibrationData, noise: TrackerNoise) -> tuple[np.ndarray, np.ndarray]:
    """(whitened Jacobian (K*6, 42), the same with unit columns) at ``theta`` for ``data``'s poses."""
    weights = whitening(theta, data.positions, data.rotations, data.frames, noise)
    flat = whitened(theta, data.positions, data.rotations, data.readings, weights)[1].reshape(-1, PARAMETER_COUNT)
    scale = np.linalg.norm(flat, axis=0)
    return flat, flat / np.where(scale > 0, scale, 1.0)


def identifiability(theta: np.ndarray, data: CalibrationData, noise: TrackerNoise) -> tuple[float, np.ndarray]:
    """(condition number of the column-scaled whitened Jacobian, predicted standard deviations (42,) m) of
    the parameters from poses like ``data``'s (only their poses and frame counts matter)."""
    flat, scaled = _scaled_jacobian(theta, data, noise)
    singular = np.linalg.svd(scaled, compute_uv=False)
    condition = float(singular[0] / singular[-1]) if singular[-1] > 0 else float("inf")
    try:
        std = np.sqrt(np.clip(np.diag(np.linalg.inv(flat.T @ flat)), 0.0, None))
    except np.linalg.LinAlgError:
        std = np.full(PARAMETER_COUNT, np.inf)
    return condition, std


def _weakest(theta: np.ndarray, data: CalibrationData, noise: TrackerNoise) -> str:
    """The parameters that dominate the least determined direction, for a refusal's message."""
    direction = np.linalg.svd(_scaled_jacobian(theta, data, noise)[1])[2][-1]
    names = parameter_names()
    return ", ".join(names[i] for i in np.argsort(-np.abs(direction))[:4])


def _fit(theta0: np.ndarray, data: CalibrationData, noise: TrackerNoise) -> tuple[np.ndarray, np.ndarray]:
    """(theta, whitened Jacobian (K*6, 42)) of the maximum-likelihood fit; the whitening is evaluated at the
    start and again once at the first solution (it depends on the geometry only slightly)."""
    from scipy.optimize import least_squares  # here: importing scipy costs every command line ~30 MB

    theta = theta0
    for _ in range(2):
        weights = whitening(theta, data.positions, data.rotations, data.frames, noise)

        def residuals(t, w=weights):
            return whitened(t, data.positions, data.rotations, data.readings, w)[0].ravel()

        def jacobian(t, w=weights):
            return whitened(t, data.positions, data.rotations, data.readings, w)[1].reshape(-1, PARAMETER_COUNT)

        theta = least_squares(residuals, theta, jac=jacobian, method="lm", xtol=1e-12, ftol=1e-12).x
    weights = whitening(theta, data.positions, data.rotations, data.frames, noise)
    return theta, whitened(theta, data.positions, data.rotations, data.readings, weights)[1].reshape(
        -1, PARAMETER_COUNT)


def _pose_figures(theta: np.ndarray, data: CalibrationData, noise: TrackerNoise) -> tuple[np.ndarray, np.ndarray]:
    """(chi-square (K,), strut residual RMS (K,) m) of every pose of ``data`` at ``theta``."""
    weights = whitening(theta, data.positions, data.rotations, data.frames, noise)
    res = whitened(theta, data.positions, data.rotations, data.readings, weights)[0]
    raw = predicted_readings(theta, data.positions, data.rotations) - data.readings
    return (res ** 2).sum(axis=1), np.sqrt((raw ** 2).mean(axis=1))


def identify(nominal: Robot, data: CalibrationData, noise: TrackerNoise) -> CalibrationResult:
    """The calibrated parameters from ``data``, starting from the drawing ``nominal``.

    Raises:
        CalibrationError: BAD_DATA, TOO_FEW_POSES, UNIDENTIFIABLE (naming the least determined parameters)
            or TOO_MANY_OUTLIERS (more than ``MAX_DROPPED_FRACTION`` of the poses disagree with the fit).
    """
    check_data(data)
    theta0 = parameters_of(nominal)
    condition, _ = identifiability(theta0, data, noise)
    if not condition < CONDITION_MAX:
        raise CalibrationError("UNIDENTIFIABLE", f"calibration data: the poses leave parameters undetermined "
                                                 f"(condition number {condition:.3g} > {CONDITION_MAX:g}); least "
                                                 f"determined: {_weakest(theta0, data, noise)}")
    used = np.ones(data.count, bool)
    dropped: list[DroppedPose] = []
    max_dropped = int(MAX_DROPPED_FRACTION * data.count)
    while True:
        theta, jac = _fit(theta0, data.subset(used), noise)
        chi2, rms = _pose_figures(theta, data, noise)
        worst = int(np.argmax(np.where(used, chi2, -np.inf)))
        if chi2[worst] <= OUTLIER_CHI2:
            break
        if len(dropped) >= max_dropped or used.sum() - 1 < MIN_POSES:
            raise CalibrationError("TOO_MANY_OUTLIERS", f"calibration data: {len(dropped) + 1} of {data.count} poses "
                                                        f"disagree with the fit beyond the tracker's noise (worst: "
                                                        f"pose {worst + 1}, chi-square {chi2[worst]:.3g}); the data "
                                                        "are not trustworthy")
        dropped.append(DroppedPose(worst, float(chi2[worst]), float(rms[worst])))
        used[worst] = False
    dof = max(int(used.sum()) * 6 - PARAMETER_COUNT, 1)
    reduced = float(chi2[used].sum() / dof)
    covariance = np.linalg.inv(jac.T @ jac) * max(reduced, 1.0)
    return CalibrationResult(theta, covariance, used, chi2, rms, tuple(dropped), reduced, condition)
