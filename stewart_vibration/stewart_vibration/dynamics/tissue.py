"""Soft tissue around the fracture as a 6-DoF visco-elastic load on the platform (pure numpy).

The distal fragment (held by the platform) is pulled back by muscles and ligaments as it is distracted
and aligned. The model is a spring-damper about a rest pose -- the platform pose at which the tissue is
slack -- acting at a tissue centre fixed in the platform (e.g. the fracture gap on the tibia axis), with
separate stiffness and damping per direction in the tissue frame: the platform frame at the rest pose,
whose z axis is the tibia axis (axial), x and y lateral, rotation about z torsion, about x and y bending.

With R_r, p_r the rest rotation and position, c the centre (platform frame), R, p, v, w the platform's
rotation, origin, origin velocity and angular velocity (base frame) and r = R c:

    u     = R_r^T (p + r - p_r - R_r c)          translation of the centre, tissue frame (u_z > 0: distraction)
    theta = log(R_r^T R)                         rotation from the rest pose, tissue frame (rotation vector)
    v_t   = R_r^T (v + w x r),  w_t = R_r^T w    their rates
    F_t   = -[k_lat u_x + c_lat v_x,  k_lat u_y + c_lat v_y,  preload + f(u_z) + c_ax v_z]
    M_t   = -[k_bend theta_x + c_bend w_x,  k_bend theta_y + c_bend w_y,  k_tor theta_z + c_tor w_z]

f is the axial spring: k_ax u in compression (u <= 0); in distraction either linear, exponential
k_ax lambda (exp(u / lambda) - 1) (slope k_ax at 0, growing e-fold every lambda), or piecewise linear
(slopes k_j from breakpoints u_j). The preload (N, >= 0) pulls the fragment back along the axis (toward
the base) at any distraction: muscle tone. The wrench on the platform, base frame, moment about the
platform origin (the convention of ``dynamics.leg_forces`` and platform/external_wrench_estimate):

    F = R_r F_t,   M = R_r M_t + r x F

Parameters come from a YAML file (config/tissue.yaml holds EXAMPLE values, not patient data);
``load_tissue`` reads it. ``tissue_wrench`` is vectorised over leading batch dimensions;
``tissue_wrench_from_state`` takes rotation matrices (the emulator's MuJoCo state) instead of
roll-pitch-yaw. ``wrench_about_point`` moves the moment to another point, e.g. the centre of mass for
MuJoCo's ``xfrc_applied`` (force at the body's centre of mass, world frame).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, cast

import numpy as np

from ..config_values import Plausible, as_number, as_vector, check_keys, lookup
from ..errors import ConfigError, StewartError
from ..input_checks import as_batch
from ..install import config_path
from ..kinematics import check_pose
from ..kinematics.rotations import rotation_from_rpy, so3_log
from ..paper import paper_pose
from ..robot import Robot, read_only_array
from ..safe_yaml import load_yaml, short_repr

STIFFENING_TYPES = ("none", "exponential", "piecewise_linear")
_KEYS = {"name", "note", "rest_pose", "center_m", "axial", "lateral", "torsional", "bending", "preload_n",
         "stiffening"}


@dataclass(frozen=True)
class TissueModel:
    """Tissue parameters (SI). rest_pose (6,) [x, y, z, roll, pitch, yaw]; center (3,) platform frame (m);
    stiffness (6,) [lateral, lateral, axial (N/m), bending, bending, torsional (N m/rad)] and damping (6,)
    (N s/m, N m s/rad) in the tissue frame; preload (N, pulls back along the axis); stiffening "none" |
    "exponential" (length_m) | "piecewise_linear" (breakpoints_m [n] from 0 up, slopes_n_m [n], the first
    equal to the axial stiffness)."""

    rest_pose: np.ndarray
    center: np.ndarray
    stiffness: np.ndarray
    damping: np.ndarray
    preload: float = 0.0
    stiffening: str = "none"
    length_m: float = 0.0
    breakpoints_m: np.ndarray | None = None
    slopes_n_m: np.ndarray | None = None
    name: str = "tissue"
    source: str = ""

    if TYPE_CHECKING:  # derived in __post_init__ (not fields at run time)
        _rest: np.ndarray = field(init=False)
        _rest_center: np.ndarray = field(init=False)
        _rest_list: list[list[float]] = field(init=False)
        _rest_center_list: list[float] = field(init=False)
        _center_list: list[float] = field(init=False)
        _stiffness_list: list[float] = field(init=False)
        _damping_list: list[float] = field(init=False)

    def __post_init__(self):
        for name in ("rest_pose", "center", "stiffness", "damping", "breakpoints_m", "slopes_n_m"):
            if getattr(self, name) is not None:  # read-only: the plain-float copies below must stay in step
                object.__setattr__(self, name, read_only_array(getattr(self, name)))
        rest = rotation_from_rpy(self.rest_pose[3:])
        object.__setattr__(self, "_rest", rest)
        object.__setattr__(self, "_rest_center", self.rest_pose[:3] + rest @ self.center)
        # plain-float copies for tissue_wrench_single
        object.__setattr__(self, "_rest_list", rest.tolist())
        object.__setattr__(self, "_rest_center_list", self._rest_center.tolist())
        object.__setattr__(self, "_center_list", self.center.tolist())
        object.__setattr__(self, "_stiffness_list", self.stiffness.tolist())
        object.__setattr__(self, "_damping_list", self.damping.tolist())

    @property
    def rest_rotation(self) -> np.ndarray:
        """The platform's rotation at the rest pose (3, 3): tissue frame -> base frame."""
        return self._rest

    @property
    def rest_center(self) -> np.ndarray:
        """The centre at the rest pose, base frame (m)."""
        return self._rest_center

    @property
    def axis(self) -> np.ndarray:
        """The tibia axis (tissue z) in the base frame."""
        return self._rest[:, 2].copy()

    def axial_spring(self, distraction) -> np.ndarray:
        """Axial spring force f(u) (N, resisting) at axial displacements u [...] (m); without the preload."""
        u = np.asarray(distraction, dtype=float)
        k = self.stiffness[2]
        pos = np.maximum(u, 0.0)
        if self.stiffening == "exponential":
            grown = k * self.length_m * np.expm1(pos / self.length_m)
        elif self.stiffening == "piecewise_linear":
            # both set with this stiffening (load_tissue checks them)
            starts, slopes = cast(np.ndarray, self.breakpoints_m), cast(np.ndarray, self.slopes_n_m)
            ends = np.append(starts[1:], np.inf)
            grown = sum(s * np.clip(pos - a, 0.0, b - a) for a, b, s in zip(starts, ends, slopes))
        else:
            grown = k * pos
        return np.where(u > 0, grown, k * u)

    def axial_spring_scalar(self, u: float) -> float:
        """``axial_spring`` for one float (plain Python: the emulator's per-block path)."""
        k = self._stiffness_list[2]
        if u <= 0.0 or self.stiffening == "none":
            return k * u
        if self.stiffening == "exponential":
            return k * self.length_m * math.expm1(u / self.length_m)
        return float(self.axial_spring(u))


def _cross(a, b):
    """a x b over the last axis (np.cross costs ~20 us per call on one vector: the emulator calls this per block)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a1 * b2 - a2 * b1
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


def tissue_displacement(model: TissueModel, position, rotation):
    """(u [..., 3] m, theta [..., 3] rad, arm r = R c [..., 3]) of the tissue centre, tissue frame.

    Args:
        model: the tissue model.
        position: platform origins p [..., 3] (base frame, m).
        rotation: platform rotations R [..., 3, 3].

    Returns:
        (u, theta, arm): u = R_r^T (p + R c - p_r - R_r c) [..., 3] (m) and theta = log(R_r^T R) [..., 3]
        (rad), both in the tissue frame; arm r = R c [..., 3] (base frame, m).
    """
    rest = model.rest_rotation
    arm = rotation @ model.center
    u = (position + arm - model.rest_center) @ rest
    return u, so3_log(rest.T @ rotation), arm


def tissue_wrench_from_state(model: TissueModel, position, rotation, velocity=None, omega=None) -> np.ndarray:
    """Wrench [..., 6] = [F, M] (N, N m about the platform origin, base frame) of the tissue on the platform at
    positions [..., 3], rotations [..., 3, 3] and, optionally, origin velocities and angular velocities [..., 3].

    Args:
        model: the tissue model.
        position: platform origins p [..., 3] (base frame, m).
        rotation: platform rotations R [..., 3, 3].
        velocity: optional origin velocities v [..., 3] (base frame, m/s); None = at rest: no damping.
        omega: optional angular velocities w [..., 3] (base frame, rad/s); None = 0; ignored when
            ``velocity`` is None.

    Returns:
        [F, M] [..., 6] (N, N m about the platform origin; base frame).
    """
    u, theta, arm = tissue_displacement(model, position, rotation)
    k, c = model.stiffness, model.damping
    force_t = -k[:3] * u
    force_t[..., 2] = -(model.preload + model.axial_spring(u[..., 2]))
    moment_t = -k[3:] * theta
    if velocity is not None:
        rest = model.rest_rotation
        omega = np.zeros_like(velocity) if omega is None else omega
        force_t = force_t - c[:3] * ((velocity + _cross(omega, arm)) @ rest)
        moment_t = moment_t - c[3:] * (omega @ rest)
    rest_t = model.rest_rotation.T
    force = force_t @ rest_t
    moment = moment_t @ rest_t + _cross(arm, force)
    return np.concatenate([force, moment], axis=-1)


def tissue_wrench_single(model: TissueModel, position, rotation, velocity, omega) -> list[float]:
    """``tissue_wrench_from_state`` for one state in plain Python floats (~10x faster than numpy on 3-vectors:
    the emulator evaluates it every state period).

    Args:
        model: the tissue model.
        position: platform origin p (3,) (base frame, m).
        rotation: platform rotation R, a (3, 3) numpy array.
        velocity: origin velocity v (3,) (base frame, m/s).
        omega: angular velocity w (3,) (base frame, rad/s).

    Returns:
        [F_x, F_y, F_z, M_x, M_y, M_z] as six floats (N, N m about the platform origin; base frame).
    """
    px, py, pz = position[0], position[1], position[2]
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = rotation.tolist()
    cx, cy, cz = model._center_list
    ax, ay, az = r00 * cx + r01 * cy + r02 * cz, r10 * cx + r11 * cy + r12 * cz, r20 * cx + r21 * cy + r22 * cz
    (q00, q01, q02), (q10, q11, q12), (q20, q21, q22) = model._rest_list
    ox, oy, oz = model._rest_center_list
    dx, dy, dz = px + ax - ox, py + ay - oy, pz + az - oz
    u0, u1, u2 = q00 * dx + q10 * dy + q20 * dz, q01 * dx + q11 * dy + q21 * dz, q02 * dx + q12 * dy + q22 * dz
    # rel = R_r^T R and its rotation vector (so3_log)
    m = [[q00 * r00 + q10 * r10 + q20 * r20, q00 * r01 + q10 * r11 + q20 * r21, q00 * r02 + q10 * r12 + q20 * r22],
         [q01 * r00 + q11 * r10 + q21 * r20, q01 * r01 + q11 * r11 + q21 * r21, q01 * r02 + q11 * r12 + q21 * r22],
         [q02 * r00 + q12 * r10 + q22 * r20, q02 * r01 + q12 * r11 + q22 * r21, q02 * r02 + q12 * r12 + q22 * r22]]
    angle = math.acos(min(1.0, max(-1.0, (m[0][0] + m[1][1] + m[2][2] - 1.0) / 2.0)))
    sin = math.sin(angle)
    scale = 0.5 + angle * angle / 12.0 if angle < 1e-6 else angle / (2.0 * (sin if sin != 0 else 1.0))
    t0, t1, t2 = scale * (m[2][1] - m[1][2]), scale * (m[0][2] - m[2][0]), scale * (m[1][0] - m[0][1])
    kx, ky, kz, kbx, kby, ktz = model._stiffness_list
    cxd, cyd, czd, cbx, cby, ctz = model._damping_list
    wx, wy, wz = omega[0], omega[1], omega[2]
    vx, vy, vz = velocity[0] + wy * az - wz * ay, velocity[1] + wz * ax - wx * az, velocity[2] + wx * ay - wy * ax
    vt0, vt1, vt2 = q00 * vx + q10 * vy + q20 * vz, q01 * vx + q11 * vy + q21 * vz, q02 * vx + q12 * vy + q22 * vz
    wt0, wt1, wt2 = q00 * wx + q10 * wy + q20 * wz, q01 * wx + q11 * wy + q21 * wz, q02 * wx + q12 * wy + q22 * wz
    f0, f1 = -kx * u0 - cxd * vt0, -ky * u1 - cyd * vt1
    f2 = -(model.preload + model.axial_spring_scalar(u2)) - czd * vt2
    m0, m1, m2 = -kbx * t0 - cbx * wt0, -kby * t1 - cby * wt1, -ktz * t2 - ctz * wt2
    fx, fy, fz = q00 * f0 + q01 * f1 + q02 * f2, q10 * f0 + q11 * f1 + q12 * f2, q20 * f0 + q21 * f1 + q22 * f2
    mx = q00 * m0 + q01 * m1 + q02 * m2 + ay * fz - az * fy
    my = q10 * m0 + q11 * m1 + q12 * m2 + az * fx - ax * fz
    mz = q20 * m0 + q21 * m1 + q22 * m2 + ax * fy - ay * fx
    return [fx, fy, fz, mx, my, mz]


def tissue_wrench(model: TissueModel, pose, twist=None) -> np.ndarray:
    """Wrench [..., 6] of the tissue on the platform at poses [..., 6] with optional twists [..., 6] = [v, w]
    (base frame; None = at rest). Base frame, moment about the platform origin (see the module docstring).

    Args:
        model: the tissue model.
        pose: platform poses [..., 6] (m, rad).
        twist: optional platform twists [..., 6] = [v, w] (m/s, rad/s; base frame), broadcast against
            ``pose``; None = at rest (no damping).

    Returns:
        [F, M] [..., 6] (N, N m about the platform origin; base frame).

    Raises:
        InvalidInputError: ``pose`` or ``twist`` is not numeric, not [..., 6] or not finite (``as_batch``).
        ValueError: the batch shapes of ``pose`` and ``twist`` do not broadcast (numpy).
    """
    pose = as_batch(pose, 6, "pose")
    if twist is None:
        return tissue_wrench_from_state(model, pose[..., :3], rotation_from_rpy(pose[..., 3:]))
    twist = as_batch(twist, 6, "twist")
    pose, twist = np.broadcast_arrays(pose, twist)
    return tissue_wrench_from_state(model, pose[..., :3], rotation_from_rpy(pose[..., 3:]), twist[..., :3],
                                    twist[..., 3:])


def wrench_about_point(wrench, arm) -> np.ndarray:
    """The same wrench [..., 6] with its moment about the point at ``arm`` [..., 3] from the original
    reference point: [F, M - arm x F] (e.g. the centre of mass for MuJoCo's xfrc_applied).

    Args:
        wrench: wrenches [..., 6] = [F, M] (N, N m) about the original reference point.
        arm: vectors [..., 3] (m) from the original reference point to the new one, in the wrench's frame.

    Returns:
        [F, M - arm x F] [..., 6] (N, N m about the new point).
    """
    wrench = np.asarray(wrench, dtype=float)
    force = wrench[..., :3]
    return np.concatenate([force, wrench[..., 3:] - _cross(arm, force)], axis=-1)


# -- configuration ----------------------------------------------------------------------------------

# Plausible ranges of the tissue file's values (SI). Soft tissue around a long-bone fracture is of the
# order of 10 N/mm and a few N m per 10 deg; these allow two orders of magnitude more, and a stiffening
# length of at least 1 mm (the exponential spring grows e-fold per length_m: shorter makes it a wall).
_PLAUSIBLE = {
    "stiffness_n_m": Plausible(0.0, 1e6, "N/m"),
    "damping_n_s_m": Plausible(0.0, 1e4, "N s/m"),
    "stiffness_nm_rad": Plausible(0.0, 1e4, "N m/rad"),
    "damping_nm_s_rad": Plausible(0.0, 100.0, "N m s/rad"),
    "preload_n": Plausible(0.0, 1e3, "N"),
    "center_m": Plausible(-0.5, 0.5, "m"),
    "length_m": Plausible(1e-3, 1.0, "m"),
    "breakpoints_m": Plausible(0.0, 0.5, "m"),
    "slopes_n_m": Plausible(0.0, 1e6, "N/m"),
}
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


def _number(tree: dict, key: str, where: str, kind: str | None = None) -> float:
    """The number at ``tree[key]`` in its plausible range (``kind``: the range's name, default the key)."""
    if not isinstance(tree, dict) or key not in tree:
        raise ConfigError(f"{where}: missing field '{key}'")
    return as_number(tree[key], key, where, _PLAUSIBLE[kind or key])


def _pair(tree: dict, key: str, units: tuple[str, str], where: str) -> tuple[float, float]:
    stiffness, damping = f"stiffness_{units[0]}", f"damping_{units[1]}"
    part = tree.get(key)
    if not isinstance(part, dict):
        raise ConfigError(f"{where}: '{key}' needs {stiffness} and {damping}, got {short_repr(part)}")
    check_keys(part, {stiffness, damping}, where, key)
    return (as_number(lookup(tree, f"{key}.{stiffness}", where), f"{key}.{stiffness}", where, _PLAUSIBLE[stiffness]),
            as_number(lookup(tree, f"{key}.{damping}", where), f"{key}.{damping}", where, _PLAUSIBLE[damping]))


def resolve_pose(robot: Robot, value, key: str, where: str) -> np.ndarray:
    """``home``, ``paper`` or 6 numbers [x, y, z, roll, pitch, yaw] (m, rad) -> pose (6,).

    Args:
        robot: the robot (its home pose and the paper pose).
        value: "home", "paper", or a list of six numbers (m, rad).
        key: the value's key, for the error message.
        where: the file, for the error message.

    Returns:
        The pose (6,) (m, rad), a new array.

    Raises:
        ConfigError: naming ``key``: ``value`` is neither "home", "paper" nor a list of six finite numbers.
    """
    if value == "home":
        return robot.home_pose.copy()
    if value == "paper":
        return paper_pose(robot)
    if not (isinstance(value, list) and len(value) == 6):
        raise ConfigError(f"{where}: '{key}' needs home, paper or 6 numbers [x, y, z, roll, pitch, yaw], got "
                          f"{short_repr(value)}")
    return as_vector(value, key, where, 6)


def _stiffening(tree: dict, k_axial: float, where: str) -> tuple[str, float, np.ndarray | None, np.ndarray | None]:
    """(type, length_m, breakpoints_m, slopes) of the ``stiffening`` section."""
    stiff = tree.get("stiffening") or {"type": "none"}
    if not isinstance(stiff, dict) or stiff.get("type", "none") not in STIFFENING_TYPES:
        raise ConfigError(f"{where}: 'stiffening.type' must be one of {list(STIFFENING_TYPES)}, got "
                          f"{short_repr(stiff.get('type') if isinstance(stiff, dict) else stiff)}")
    kind = stiff.get("type", "none")
    allowed = {"none": {"type"}, "exponential": {"type", "length_m"},
               "piecewise_linear": {"type", "breakpoints_m", "stiffness_n_m"}}[kind]
    check_keys(stiff, allowed, where, f"stiffening ({kind})")
    if kind == "exponential":
        return kind, as_number(lookup(stiff, "length_m", where), "stiffening.length_m", where,
                               _PLAUSIBLE["length_m"]), None, None
    if kind == "piecewise_linear":
        starts, slopes = (lookup(stiff, key, where) for key in ("breakpoints_m", "stiffness_n_m"))
        count = len(starts) if isinstance(starts, list) else 0
        if not 1 <= count <= 100:
            raise ConfigError(f"{where}: 'stiffening.breakpoints_m' must be a list of 1 to 100 numbers, got "
                              f"{short_repr(starts)}")
        starts = as_vector(starts, "stiffening.breakpoints_m", where, count, _PLAUSIBLE["breakpoints_m"])
        slopes = as_vector(slopes, "stiffening.stiffness_n_m", where, count, _PLAUSIBLE["slopes_n_m"])
        if starts[0] != 0.0 or (np.diff(starts) <= 0).any() or slopes[0] != k_axial:
            raise ConfigError(f"{where}: piecewise_linear needs breakpoints_m strictly increasing from 0 and as "
                              "many stiffness_n_m >= 0, the first equal to axial.stiffness_n_m")
        return kind, 0.0, starts, slopes
    return kind, 0.0, None, None


def tissue_from_dict(tree: dict, robot: Robot, source: str = "<dict>") -> TissueModel:
    """Build a TissueModel from the parsed YAML tree (see config/tissue.yaml); ConfigError with the reason.

    Every value is checked against its plausible range (``_PLAUSIBLE``), the rest pose must be one the
    robot can take (``kinematics.check_pose``), and the worst-case wrench near the rest pose must stay
    within the plausible bound and finite within the robot's reach (``check_tissue_wrench``).

    Args:
        tree: the parsed YAML mapping (keys name, note, rest_pose, center_m, axial, lateral, torsional,
            bending, preload_n, stiffening).
        robot: the robot (for rest_pose "home" / "paper", its reach and its strut limits).
        source: where the tree comes from, for error messages and ``TissueModel.source``.

    Returns:
        The TissueModel (SI units).

    Raises:
        ConfigError: one line naming the key: the tree is not a mapping, has unknown keys, a missing,
            mistyped, non-finite or implausible value, a rest pose the robot cannot take, a bad stiffening
            section, or a worst-case wrench beyond the bound.
    """
    where = f"tissue config {source}"
    if not isinstance(tree, dict):
        raise ConfigError(f"{where}: top level must be a mapping")
    check_keys(tree, _KEYS, where)
    rest = resolve_pose(robot, tree.get("rest_pose", "home"), "rest_pose", where)
    try:
        check_pose(robot, rest)
    except StewartError as exc:
        raise ConfigError(f"{where}: 'rest_pose' {rest.tolist()} cannot be taken by the robot: "
                          f"{type(exc).__name__}: {exc}") from None
    center = as_vector(tree.get("center_m", [0.0, 0.0, 0.0]), "center_m", where, 3, _PLAUSIBLE["center_m"])
    k_ax, c_ax = _pair(tree, "axial", ("n_m", "n_s_m"), where)
    k_lat, c_lat = _pair(tree, "lateral", ("n_m", "n_s_m"), where)
    k_tor, c_tor = _pair(tree, "torsional", ("nm_rad", "nm_s_rad"), where)
    k_bend, c_bend = _pair(tree, "bending", ("nm_rad", "nm_s_rad"), where)
    preload = _number(tree, "preload_n", where) if "preload_n" in tree else 0.0
    kind, length, starts, slopes = _stiffening(tree, k_ax, where)
    for key in ("name", "note"):
        if not isinstance(tree.get(key, ""), str):
            raise ConfigError(f"{where}: '{key}' must be text, got {short_repr(tree[key])}")
    model = TissueModel(
        rest_pose=rest, center=center,
        stiffness=np.array([k_lat, k_lat, k_ax, k_bend, k_bend, k_tor]),
        damping=np.array([c_lat, c_lat, c_ax, c_bend, c_bend, c_tor]),
        preload=preload, stiffening=kind, length_m=length, breakpoints_m=starts, slopes_n_m=slopes,
        name=str(tree.get("name", "tissue")), source=source)
    check_tissue_wrench(model, robot, where)
    return model


def load_tissue(path, robot: Robot) -> TissueModel:
    """Tissue model from a YAML file; a bare file name is looked up in the config directory too.

    Args:
        path: the YAML file (str or Path); a relative path that is not a file is tried in
            ``default_config_dir()``.
        robot: the robot (for rest_pose "home" / "paper").

    Returns:
        The TissueModel.

    Raises:
        ConfigError: the file cannot be read safely (``safe_yaml.load_yaml``), a value is bad
            (``tissue_from_dict``), or the config directory is needed and not found (``default_config_dir``).
    """
    path = config_path(path)
    return tissue_from_dict(load_yaml(path, "tissue config"), robot, str(path))


def load_tissue_option(value: str | None, robot: Robot) -> TissueModel | None:
    """A node's ``tissue_config`` parameter: '' (or None) = no tissue, else ``load_tissue``.

    Args:
        value: the parameter: a YAML path, '' or None.
        robot: the robot.

    Returns:
        The TissueModel, or None for '' / None.

    Raises:
        ConfigError: as ``load_tissue``.
    """
    return load_tissue(value, robot) if value else None


__all__ = [
    "TissueModel",
    "WrenchBound",
    "check_tissue_wrench",
    "load_tissue",
    "load_tissue_option",
    "resolve_pose",
    "tissue_displacement",
    "tissue_from_dict",
    "tissue_wrench_bound",
    "tissue_wrench",
    "tissue_wrench_from_state",
    "tissue_wrench_single",
    "wrench_about_point",
]
