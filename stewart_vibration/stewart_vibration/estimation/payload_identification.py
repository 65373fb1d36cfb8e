"""The payload the platform carries and the load cells' offsets, from the cells at rest (pure numpy).

At rest the axial force each strut transmits is gravity's share alone: the legs', the platform's and the
payload's. A payload of mass m with its centre of mass at c (platform frame) differs from the model's (m0, c0)
by the wrench of its extra weight on the platform, linear in dm = m - m0 and the first moment dq = m c - m0 c0:

    dW = [dm g; (R dq) x g]    (base frame, about the platform origin; g the gravity vector)

and the model's leg forces are affine in a wrench on the platform, F = F0 + G dW (``leg_forces``' external
wrench). So each pose's mean cell readings are, with each cell's constant offset o,

    cells = F0(pose) + G(pose) [dm g; -[g]x R dq] + o

linear in the ten unknowns (dm, dq, o), identified by least squares over the calibration's poses. The payload's
inertia cannot be seen at rest; it is scaled with the mass (a payload of the same shape). The standard
deviations come from the cells' noise (declared or, when larger, the residual's).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..calibration.geometry_parameters import robot_with_parameters
from ..calibration.identification import CalibrationData, CalibrationResult
from ..dynamics.newton_euler import leg_forces
from ..errors import CalibrationError
from ..kinematics.rotations import rpy_from_rotation, skew
from ..robot import RigidBody, Robot

PARAMETERS = ("payload_mass_kg", "payload_moment_x_kg_m", "payload_moment_y_kg_m", "payload_moment_z_kg_m",
              *(f"load_cell_offset_{i + 1}_n" for i in range(6)))
MAX_CONDITION = 1e6  # a pose set above this leaves the payload or an offset undetermined
MIN_POSES = 2  # ten unknowns, six readings per pose


@dataclass(frozen=True)
class PayloadResult:
    """The identified payload (mass kg, centre of mass (3,) m in the platform frame, the RigidBody with the
    inertia scaled by the mass), the cells' offsets (6,) N (reading minus force), the standard deviations of
    PARAMETERS (10,), the residual RMS (N) and the condition number of the (column-scaled) fit."""

    mass_kg: float
    com_m: np.ndarray
    body: RigidBody
    load_cell_offsets_n: np.ndarray
    std: np.ndarray
    residual_rms_n: float
    condition_number: float


def rest_design(robot: Robot, positions: np.ndarray, rotations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(F0 [K, 6] N: the model's strut forces at rest at the poses, A [K, 6, 10]: the cells' sensitivity to
    (dm, dq, o)) at K poses: positions [K, 3] m and rotations [K, 3, 3] (base frame)."""
    rotations = np.asarray(rotations, float)
    poses = np.column_stack([np.asarray(positions, float), rpy_from_rotation(rotations)])
    k = len(poses)
    zero = np.zeros((k, 6))
    base = leg_forces(robot, poses, zero, zero)
    unit = np.eye(6)[:, None, :]  # one unit wrench on the platform at a time, each over every pose
    sensitivity = (leg_forces(robot, np.broadcast_to(poses, (6, k, 6)), zero, zero, external_wrench=unit)
                   - base).transpose(1, 2, 0)  # G [K, 6 legs, 6 wrench]
    g = np.asarray(robot.gravity, float)
    mass_column = sensitivity[:, :, :3] @ g  # [K, 6]
    moment = -skew(g) @ rotations  # [K, 3, 3]: (R dq) x g = -[g]x R dq
    moment_columns = sensitivity[:, :, 3:] @ moment  # [K, 6, 3]
    offsets = np.broadcast_to(np.eye(6), (k, 6, 6))
    return base, np.concatenate([mass_column[:, :, None], moment_columns, offsets], axis=2)


def identify_payload(robot: Robot, positions, rotations, loads, load_noise_n: float = 0.0) -> PayloadResult:
    """The payload and cell offsets from the mean cell readings ``loads`` [K, 6] (N) at rest at K poses
    (positions [K, 3] m, rotations [K, 3, 3], base frame: the tracker's means), with ``robot``'s geometry (the
    calibrated one) and its payload as the starting model; ``load_noise_n``: the standard deviation of one
    pose's mean reading (0: from the residual).

    Raises:
        CalibrationError: BAD_DATA for readings that are not finite or of the wrong shape, or a mass that is not
            positive; TOO_FEW_POSES below MIN_POSES; UNIDENTIFIABLE when the poses leave a parameter undetermined
            (a condition number above MAX_CONDITION).
    """
    loads = np.asarray(loads, float)
    if loads.ndim != 2 or loads.shape[1] != 6 or not np.isfinite(loads).all():
        raise CalibrationError("BAD_DATA", f"payload: the load cells' means must be finite [K, 6] (N), got shape "
                                           f"{loads.shape}{'' if loads.ndim != 2 else ' with gaps'}")
    if len(loads) < MIN_POSES:
        raise CalibrationError("TOO_FEW_POSES", f"payload: the cells' offsets and the payload need {MIN_POSES} "
                                                f"poses or more, got {len(loads)}")
    base, design = rest_design(robot, positions, rotations)
    a = design.reshape(-1, 10)
    b = (loads - base).reshape(-1)
    scale = np.linalg.norm(a, axis=0)
    condition = float(np.linalg.cond(a / scale))
    if not condition <= MAX_CONDITION:
        raise CalibrationError("UNIDENTIFIABLE", f"payload: the poses leave the payload or an offset undetermined "
                                                 f"(condition number {condition:.3g})")
    x = np.linalg.lstsq(a / scale, b, rcond=None)[0] / scale
    residual = b - a @ x
    sigma = max(float(load_noise_n), float(np.sqrt(residual @ residual / max(len(b) - 10, 1))))
    std = sigma * np.sqrt(np.diag(np.linalg.inv(a.T @ a)))
    nominal = robot.payload
    mass = nominal.mass + float(x[0])
    if not mass > 0:
        raise CalibrationError("BAD_DATA", f"payload: the cells say the payload's mass is {mass:.3f} kg")
    com = (nominal.mass * np.asarray(nominal.com) + x[1:4]) / mass
    body = RigidBody(mass, com, np.asarray(nominal.inertia) * (mass / nominal.mass))
    return PayloadResult(mass, com, body, x[4:].copy(), std, float(np.sqrt(np.mean(residual**2))), condition)


def payload_tree(result: PayloadResult, nominal: RigidBody) -> dict:
    """The robot file's keys of an identified payload (plain values): ``inertia.payload_identified`` (the body
    the model uses in place of the drawing's payload), ``load_cells.offsets_n`` and the identification's figures
    for the ``calibration`` section (``payload``)."""
    def rounded(values, digits: int = 9) -> list:
        return [round(float(v), digits) for v in np.asarray(values).ravel()]

    return {
        "payload_identified": {"mass_kg": round(result.mass_kg, 6), "com_m": rounded(result.com_m),
                               "inertia_kg_m2": rounded(np.diag(result.body.inertia))},
        "load_cells": {"offsets_n": rounded(result.load_cell_offsets_n, 6)},
        "provenance": {"nominal_mass_kg": float(nominal.mass), "nominal_com_m": rounded(nominal.com),
                       "residual_rms_n": float(f"{result.residual_rms_n:.3g}"),
                       "condition_number": round(result.condition_number, 2),
                       "parameter_std": {name: float(f"{s:.3g}") for name, s in zip(PARAMETERS, result.std)}},
    }


def calibrated_load(robot: Robot, fit: CalibrationResult, data: CalibrationData, loads: np.ndarray
                    ) -> tuple[dict | None, str]:
    """The payload and the load cells' offsets of a kinematic calibration: from the mean cells ``loads`` [K, 6]
    (N) of its poses at rest (``data``), the poses ``fit`` used, on the geometry it identified, starting from
    ``robot``'s payload. Returns (``payload_tree`` for the robot file, what to report); (None, why) when a cell
    did not report in some window or the poses cannot tell the payload from the offsets: the geometry stands
    without them."""
    used = fit.used
    if not np.isfinite(loads[used]).all():
        return None, "payload not identified: the load cells did not report in every window"
    try:
        result = identify_payload(robot_with_parameters(robot, fit.theta), data.positions[used],
                                  data.rotations[used], loads[used])
    except CalibrationError as exc:
        return None, f"payload not identified: {exc}"
    return payload_tree(result, robot.payload), (
        f"payload {result.mass_kg:.4f} kg (+- {result.std[0]:.4f}), centre of mass "
        f"{np.round(result.com_m * 1e3, 2).tolist()} mm, load cell residual RMS {result.residual_rms_n:.4f} N")
