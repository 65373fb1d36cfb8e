"""Reduction accuracy as a surgeon states it (pure numpy): the distal fragment's residual displacement,
angulation and rotation at the fracture site, between the pose reached and the pose planned.

The fragment is carried by the platform; the fracture site is a point on the tibia axis (the platform's z
axis) given in the platform frame. Displacement (m): how far the site is from where the plan puts it.
Angulation (rad): the angle between the fragment's axis as reached and as planned. Rotation (rad): the
residual turn about the fragment's own axis (the twist of the relative rotation about platform z).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kinematics.rotations import rotation_from_rpy


@dataclass(frozen=True)
class FractureResidual:
    """Residual at the fracture site: displacement (m), angulation (rad), rotation about the axis (rad)."""

    displacement_m: float
    angulation_rad: float
    rotation_rad: float

    def record(self) -> dict:
        """The figures in the clinic's units: mm and deg."""
        return {"fracture_displacement_mm": 1e3 * self.displacement_m,
                "fracture_angulation_deg": float(np.degrees(self.angulation_rad)),
                "fracture_rotation_deg": float(np.degrees(self.rotation_rad))}


def fracture_residual(reached, planned, site_m) -> FractureResidual:
    """The residual at ``site_m`` (3,) (platform frame, m) of the pose ``reached`` against ``planned`` (both
    (6,) [x, y, z, roll, pitch, yaw], platform in the base frame)."""
    reached, planned, site = (np.asarray(v, float) for v in (reached, planned, site_m))
    r_reached, r_planned = rotation_from_rpy(reached[3:]), rotation_from_rpy(planned[3:])
    displacement = (reached[:3] + r_reached @ site) - (planned[:3] + r_planned @ site)
    axis_reached, axis_planned = r_reached[:, 2], r_planned[:, 2]
    angulation = np.arctan2(np.linalg.norm(np.cross(axis_planned, axis_reached)), axis_planned @ axis_reached)
    relative = r_planned.T @ r_reached  # in the planned fragment's frame
    # twist about z of the swing-twist decomposition: 2 atan2(q_z, q_w) with q_z = (R10 - R01) / 4 q_w and
    # 4 q_w^2 = 1 + trace R
    rotation = abs(2.0 * np.arctan2(relative[1, 0] - relative[0, 1], 1.0 + np.trace(relative)))
    return FractureResidual(float(np.linalg.norm(displacement)), float(angulation), float(rotation))
