"""What a calibration pose measures, as a function of the 42 parameters (pure numpy, vectorised over poses).

At a pose k the tracker reports the platform frame's position p_k (m) and rotation R_k in the base frame,
and the struts read q_ik = |p_k + R_k A_i - B_i| - d_i (m: encoder plus the vibration unit's sensor, the
hinge-to-hinge chain). The tracker's noise is white per frame: sigma_p per axis (m) and sigma_r per axis
(rad) about the platform frame (R_meas = R exp([nu]x)); a pose averages n_k frames. Its effect on the
predicted readings is linearised (``pose_sensitivity``), which turns every pose into 6 residuals of unit
variance (``whitened``): least squares on them is maximum likelihood, and their Jacobian gives the
parameters' covariance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry_parameters import split_parameters


@dataclass(frozen=True)
class TrackerNoise:
    """RMS noise of one tracker frame: position per axis (m), orientation per axis (rad, platform frame); and
    the strut readings' own RMS noise (m) after averaging (encoder quantisation and jitter)."""

    position_m: float
    orientation_rad: float
    reading_m: float = 1e-7


def leg_vectors(theta: np.ndarray, positions: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """Leg vectors B_i -> A_i (K, 6, 3), base frame, of poses (positions (K, 3) m, rotations (K, 3, 3))."""
    base, platform, _ = split_parameters(theta)
    return positions[:, None, :] + np.einsum("kab,ib->kia", rotations, platform) - base[None]


def predicted_readings(theta: np.ndarray, positions: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """Strut readings (K, 6) m the parameters predict at the poses: |p + R A_i - B_i| - d_i."""
    _, _, offsets = split_parameters(theta)
    return np.linalg.norm(leg_vectors(theta, positions, rotations), axis=2) - offsets


def parameter_jacobian(theta: np.ndarray, positions: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """d readings / d theta (K, 6, 42): -n_i for B_i, R^T n_i for A_i, -1 for d_i (n_i the leg's unit vector)."""
    d = leg_vectors(theta, positions, rotations)
    n = d / np.linalg.norm(d, axis=2, keepdims=True)
    count = positions.shape[0]
    jac = np.zeros((count, 6, 42))
    legs = np.arange(6)
    for axis in range(3):
        jac[:, legs, 3 * legs + axis] = -n[:, :, axis]
        jac[:, legs, 18 + 3 * legs + axis] = np.einsum("kb,kib->ki", rotations[:, :, axis], n)
    jac[:, legs, 36 + legs] = -1.0
    return jac


def pose_sensitivity(theta: np.ndarray, positions: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """d readings / d (tracker position (3), tracker rotation about the platform frame (3)): (K, 6, 6).

    Rows [n_i, A_i x R^T n_i]: a small rotation nu of the platform frame moves A_i by R (nu x A_i)."""
    _, platform, _ = split_parameters(theta)
    d = leg_vectors(theta, positions, rotations)
    n = d / np.linalg.norm(d, axis=2, keepdims=True)
    local = np.einsum("kba,kib->kia", rotations, n)  # R^T n_i
    return np.concatenate([n, np.cross(platform[None], local)], axis=2)


def whitening(theta: np.ndarray, positions: np.ndarray, rotations: np.ndarray, frames: np.ndarray,
              noise: TrackerNoise) -> np.ndarray:
    """Per pose, W_k (K, 6, 6) with W_k C_k W_k^T = I, C_k the readings' residual covariance there: the
    tracker's averaged noise through ``pose_sensitivity`` plus the readings' own."""
    sens = pose_sensitivity(theta, positions, rotations)
    per_frame = np.array([noise.position_m] * 3 + [noise.orientation_rad] * 3) ** 2
    cov = np.einsum("kia,a,kja->kij", sens, per_frame, sens) / frames[:, None, None]
    cov += noise.reading_m ** 2 * np.eye(6)
    chol = np.linalg.cholesky(cov)
    return np.linalg.inv(chol)


def whitened(theta: np.ndarray, positions: np.ndarray, rotations: np.ndarray, readings: np.ndarray,
             weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(residuals (K, 6), Jacobian (K, 6, 42)) in units of their standard deviation, for whitening ``weights``
    (K, 6, 6) from ``whitening``: W_k (predicted - measured) and W_k d predicted / d theta."""
    residual = predicted_readings(theta, positions, rotations) - readings
    return (np.einsum("kij,kj->ki", weights, residual),
            np.einsum("kij,kjp->kip", weights, parameter_jacobian(theta, positions, rotations)))
