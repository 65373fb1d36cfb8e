"""Feed-forward compensation of the vibration units from their identification (pure): the leg demands that make
the identified robot move as the decomposition plans, or why a vibration stays uncompensated.

The identification holds the platform's response H (6, 6) to each unit's demand at identified frequencies
(vibration.unit_identification); the target is the decomposition's first-order platform motion
y* = twist A exp(i phase) (base frame, [dp; dphi]); the demands are u = H(f)^-1 y*, which for a robot whose
units answer h_i and whose platform follows the kinematic map is the decomposition divided by h_i
(vibration.leg_demands.feedforward_demands), and which also takes in what couples the units (the platform's
dynamics, the tissue) at the pose it was identified at.
"""

from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError
from .decompose import VibrationDecomposition
from .unit_identification import VibrationIdentification

POSE_TOLERANCE_M = 0.002  # an identification holds within this distance of its pose
ANGLE_TOLERANCE_DEG = 1.0  # and within this rotation


def target_motion(plan: VibrationDecomposition) -> np.ndarray:
    """The decomposition's platform motion y* (6,) complex [dp (m); dphi (rad)], base frame."""
    return np.asarray(plan.twist, dtype=float) * plan.amplitude * np.exp(1j * plan.phase)


def identification_misses(ident: VibrationIdentification, pose, frequency: float,
                          pose_tolerance_m: float = POSE_TOLERANCE_M,
                          angle_tolerance_deg: float = ANGLE_TOLERANCE_DEG) -> str:
    """Why ``ident`` does not hold for a vibration at ``pose`` [6] (m, rad) and ``frequency`` (Hz): made at
    another pose (beyond the tolerances) or not covering the frequency; "" when it holds."""
    offset = np.asarray(pose, float) - np.asarray(ident.pose, float)
    distance, angle = float(np.linalg.norm(offset[:3])), float(np.degrees(np.abs(offset[3:]).max()))
    if distance > pose_tolerance_m or angle > angle_tolerance_deg:
        return (f"the identification was made {distance * 1e3:.2f} mm / {angle:.2f} deg from this pose "
                f"(tolerance {pose_tolerance_m * 1e3:g} mm / {angle_tolerance_deg:g} deg): identify the units here")
    try:
        ident.platform_response_at(frequency)
    except InvalidInputError as exc:
        return str(exc)
    return ""


def compensated_demands(ident: VibrationIdentification | None, plan: VibrationDecomposition,
                        pose_tolerance_m: float = POSE_TOLERANCE_M,
                        angle_tolerance_deg: float = ANGLE_TOLERANCE_DEG) -> tuple[np.ndarray | None, str]:
    """(demands (6,) complex m, how) of the feed-forward for ``plan``; (None, why not) when there is no
    identification, it was made at another pose (beyond the tolerances) or does not cover the frequency."""
    if ident is None:
        return None, "uncompensated: no identification of the vibration units (identification_file)"
    why_not = identification_misses(ident, plan.pose, plan.frequency, pose_tolerance_m, angle_tolerance_deg)
    if why_not:
        return None, f"uncompensated: {why_not}"
    response = ident.platform_response_at(plan.frequency)
    if np.linalg.cond(response) > 1e6:
        return None, "uncompensated: the identified platform response is singular at this frequency"
    demands = np.linalg.solve(response, target_motion(plan))
    when = ident.provenance.get("date", "")
    return demands, (f"identified feed-forward ({plan.frequency:g} Hz within {ident.frequencies[0]:g}-"
                     f"{ident.frequencies[-1]:g} Hz{', identified ' + str(when) if when else ''})")
