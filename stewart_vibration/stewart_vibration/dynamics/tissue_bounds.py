"""The worst-case wrench of a tissue model (``tissue.TissueModel``) near its rest pose, and the check that refuses
a model this robot cannot work against: force (N) and moment about the platform origin (N m) bounded over a
region of displacements (m, rad, tissue frame) and speeds (m/s, rad/s), compared with what the six struts hold.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..robot import Robot
from .tissue import TissueModel

# The region the worst-case wrench is checked over: the tissue centre up to CHECK_TRANSLATION_M from its
# rest position along each tissue axis and the platform up to CHECK_ROTATION_RAD from its rest rotation
# about each (the reduction workspace the stroke is sized for), moving at the robot's fastest strut speed
# (plus the vibration unit's).
CHECK_TRANSLATION_M = 0.020
CHECK_ROTATION_RAD = math.radians(15.0)
# Within that region the tissue's force must stay below WRENCH_FACTOR times what the six struts can hold
# together (6 strut_force_max, N), its moment below that force times the robot's characteristic length:
# a model beyond it is not a tissue this robot can work against, and its forces would wreck the physics.
WRENCH_FACTOR = 10.0


@dataclass(frozen=True)
class WrenchBound:
    """Upper bounds of a tissue's wrench over a region: force (N) and moment about the platform origin (N m)."""

    force_n: float
    moment_nm: float


def tissue_wrench_bound(model: TissueModel, translation: float, rotation: float, speed: float,
                        angular_speed: float) -> WrenchBound:
    """An upper bound of |F| and |M| over every state with the centre's displacement from rest at most
    ``translation`` (m) and the rotation from rest at most ``rotation`` (rad) along / about each tissue axis,
    and the centre's velocity at most ``speed`` (m/s) and the angular velocity at most ``angular_speed``
    (rad/s) in each component. Each spring and damper is monotone, so its largest force is at an end of
    its range; the moment adds |c| |F| for the lever arm of the centre. Non-finite (inf) where the
    exponential spring overflows.

    Returns:
        The WrenchBound (N, N m).
    """
    k, c = model.stiffness, model.damping
    with np.errstate(over="ignore"):
        spring = np.abs(model.axial_spring([-translation, translation])).max()
    lateral = k[:2] * translation + c[:2] * speed
    axial = model.preload + spring + c[2] * speed
    force = float(np.sqrt(lateral @ lateral + axial * axial))
    moment_t = k[3:] * rotation + c[3:] * angular_speed
    return WrenchBound(force, float(np.linalg.norm(moment_t) + np.linalg.norm(model.center) * force))


def robot_reach(robot: Robot, center) -> float:
    """How far (m) a point at ``center`` (platform frame) can move between two poses the robot can take: every
    platform hinge is within stroke_max of its base hinge, so the platform origin stays within stroke_max
    plus the hinge radii of the base origin."""
    radius = (robot.limits.stroke_max + np.linalg.norm(robot.base_hinges, axis=1).max()
              + np.linalg.norm(robot.platform_hinges, axis=1).max() + float(np.linalg.norm(center)))
    return 2.0 * float(radius)


def check_tissue_wrench(model: TissueModel, robot: Robot, where: str) -> WrenchBound:
    """The tissue's worst-case wrench in the check region (``CHECK_*``), refused above the plausible bound, and
    finite wherever the robot can take the platform.

    Args:
        model: the tissue model.
        robot: the robot (strut force and velocity limits, hinge geometry).
        where: the file, for the message.

    Returns:
        The WrenchBound over the check region (N, N m).

    Raises:
        ConfigError: the bound exceeds WRENCH_FACTOR x 6 strut_force_max (or the moment bound that force
            times the characteristic length), or the wrench is not finite within the robot's reach.
    """
    speed = robot.limits.strut_velocity_max + robot.vibration_unit.velocity_max
    angular = speed / robot.characteristic_length
    bound = tissue_wrench_bound(model, CHECK_TRANSLATION_M, CHECK_ROTATION_RAD, speed, angular)
    force_max = WRENCH_FACTOR * 6 * robot.limits.strut_force_max
    moment_max = force_max * robot.characteristic_length
    region = (f"within {CHECK_TRANSLATION_M * 1e3:g} mm and {math.degrees(CHECK_ROTATION_RAD):g} deg of the rest "
              f"pose at {speed:g} m/s")
    if not bound.force_n <= force_max:
        raise ConfigError(f"{where}: the tissue's force reaches {bound.force_n:.4g} N {region}, more than "
                          f"{force_max:g} N ({WRENCH_FACTOR:g} x what the six struts hold): lower the stiffness or "
                          "damping, or lengthen 'stiffening.length_m'")
    if not bound.moment_nm <= moment_max:
        raise ConfigError(f"{where}: the tissue's moment reaches {bound.moment_nm:.4g} N m {region}, more than "
                          f"{moment_max:.4g} N m: lower the stiffness or damping, or move 'center_m' nearer the "
                          "platform")
    reach = robot_reach(robot, model.center)
    far = tissue_wrench_bound(model, reach, math.pi, speed, angular)
    if not (math.isfinite(far.force_n) and math.isfinite(far.moment_nm)):
        raise ConfigError(f"{where}: the tissue's force overflows within the robot's reach ({reach:.3g} m): "
                          "lengthen 'stiffening.length_m'")
    return bound


__all__ = [
    "CHECK_ROTATION_RAD",
    "CHECK_TRANSLATION_M",
    "WRENCH_FACTOR",
    "WrenchBound",
    "check_tissue_wrench",
    "robot_reach",
    "tissue_wrench_bound",
]
