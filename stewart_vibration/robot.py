"""Robot description loaded from config/robot.yaml (the single source of truth).

Frames: ``base`` (origin at the base hinge-circle centre, z toward the
platform) and ``platform`` (origin at the platform hinge-circle centre).
"""

from __future__ import annotations

import os
import weakref
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import yaml

from .errors import ConfigError
from .install import default_config_dir

STANDARD_GRAVITY = 9.80665  # m/s^2 per g
LEG_NAMES = tuple(f"leg_{i}" for i in range(1, 7))  # joint (and TF frame) names of the struts, legs 1..6
VIB_NAMES = tuple(f"vib_{i}" for i in range(1, 7))  # joint names of the vibration units on legs 1..6

T = TypeVar("T")


def read_only_array(value):
    """A read-only float copy of an array field (frozen dataclasses must not be changed through their arrays)."""
    arr = np.array(value, dtype=float)
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True)
class RigidBody:
    """Mass (kg), centre of mass (m, body frame) and 3x3 inertia about the COM (kg m^2)."""

    mass: float
    com: np.ndarray
    inertia: np.ndarray

    def __post_init__(self):
        for name in ("com", "inertia"):
            object.__setattr__(self, name, read_only_array(getattr(self, name)))


@dataclass(frozen=True)
class LegInertia:
    """Axisymmetric strut parts: cylinder (at the base hinge) and piston (at the platform hinge).

    ``cylinder_com_offset`` e1 is measured from B_i along the leg,
    ``piston_com_offset`` e2 from A_i back along the leg (m). Inertias are
    about each part's centre of mass: transverse and axial (kg m^2).
    """

    cylinder_mass: float
    cylinder_com_offset: float
    cylinder_inertia_transverse: float
    cylinder_inertia_axial: float
    piston_mass: float
    piston_com_offset: float
    piston_inertia_transverse: float
    piston_inertia_axial: float
    vibration_unit_mass: float


@dataclass(frozen=True)
class Limits:
    """Stroke (m), strut velocity (m/s), acceleration (m/s^2) and force (N), joint angles (rad), conditioning."""

    stroke_min: float
    stroke_max: float
    strut_velocity_max: float
    strut_acceleration_max: float
    strut_force_max: float
    universal_joint_max: float
    spherical_joint_max: float
    condition_number_max: float


@dataclass(frozen=True)
class VibrationUnitLimits:
    """Per-leg vibration unit: peak amplitude (m), frequency band (Hz), peak velocity (m/s) and
    acceleration (m/s^2)."""

    amplitude_max: float
    frequency_min: float
    frequency_max: float
    acceleration_max: float
    velocity_max: float


@dataclass(frozen=True)
class LegBodies:
    """The two moving bodies of a leg as both the Newton-Euler model and the MJCF use them (SI units).

    The cylinder turns about the base hinge B_i; its centre of mass lies ``cylinder_com_offset`` from B_i
    along the leg. The piston slides in it and ends in the platform hinge A_i; its centre of mass lies
    ``piston_com_offset`` from A_i back along the leg, and the vibration unit's moving mass is lumped into
    it (its stroke is <= 100 um). Inertias are about each body's centre of mass, transverse and axial.
    """

    cylinder_mass: float
    cylinder_com_offset: float
    cylinder_inertia_transverse: float
    cylinder_inertia_axial: float
    piston_mass: float
    piston_com_offset: float
    piston_inertia_transverse: float
    piston_inertia_axial: float


@dataclass(frozen=True, eq=False)
class Robot:
    """Geometry, inertia and limits of one 6-UPS robot (SI units), immutable.

    base_hinges: (6, 3) B_i in the base frame; platform_hinges: (6, 3) A_i in
    the platform frame; home_pose: (6,) [x, y, z, roll, pitch, yaw]; gravity (3,) m/s^2 in the base
    frame. The arrays are read-only. Two robots are equal only if they are the same object (constants
    derived from a robot are cached per object, see ``derived``).
    """

    base_hinges: np.ndarray
    platform_hinges: np.ndarray
    home_pose: np.ndarray
    limits: Limits
    vibration_unit: VibrationUnitLimits
    platform: RigidBody
    payload: RigidBody
    leg: LegInertia
    gravity: np.ndarray
    source: str = ""
    characteristic_length: float = field(default=0.0)

    def __post_init__(self):
        for f in fields(self):
            if f.name in ("base_hinges", "platform_hinges", "home_pose", "gravity"):
                object.__setattr__(self, f.name, read_only_array(getattr(self, f.name)))

    @property
    def moving_body(self) -> RigidBody:
        """Platform and payload combined into one rigid body (platform frame)."""
        return derived(self, "moving_body", lambda: combine_bodies(self.platform, self.payload))

    @property
    def leg_bodies(self) -> LegBodies:
        """The cylinder and piston of every leg, the vibration unit's mass lumped into the piston."""
        leg = self.leg
        return LegBodies(
            cylinder_mass=leg.cylinder_mass,
            cylinder_com_offset=leg.cylinder_com_offset,
            cylinder_inertia_transverse=leg.cylinder_inertia_transverse,
            cylinder_inertia_axial=leg.cylinder_inertia_axial,
            piston_mass=leg.piston_mass + leg.vibration_unit_mass,
            piston_com_offset=leg.piston_com_offset,
            piston_inertia_transverse=leg.piston_inertia_transverse,
            piston_inertia_axial=leg.piston_inertia_axial,
        )


_DERIVED: weakref.WeakKeyDictionary[Robot, dict[str, Any]] = weakref.WeakKeyDictionary()


def derived(robot: Robot, key: str, build: Callable[[], T]) -> T:
    """A constant computed from ``robot`` once and kept while the robot lives (the robot is immutable).

    Args:
        robot: the robot the constant belongs to.
        key: the constant's name (one per kind of constant, e.g. "ik_matrix").
        build: computes the constant; called on the first request only.

    Returns:
        The cached constant.
    """
    cache = _DERIVED.setdefault(robot, {})
    if key not in cache:
        cache[key] = build()
    return cache[key]


def combine_bodies(a: RigidBody, b: RigidBody) -> RigidBody:
    """One rigid body equivalent to two rigidly joined ones (parallel-axis theorem)."""
    mass = a.mass + b.mass
    com = (a.mass * a.com + b.mass * b.com) / mass
    inertia = np.zeros((3, 3))
    for body in (a, b):
        r = body.com - com
        inertia += body.inertia + body.mass * (r @ r * np.eye(3) - np.outer(r, r))
    return RigidBody(mass, com, inertia)


def _get(tree: dict, dotted: str):
    node = tree
    for key in dotted.split("."):
        if not isinstance(node, dict) or key not in node:
            raise ConfigError(f"robot config: missing field '{dotted}'")
        node = node[key]
    return node


def _number(tree: dict, dotted: str, *, positive: bool = False, nonneg: bool = False) -> float:
    value = _get(tree, dotted)
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"robot config: '{dotted}' must be a number, got {value!r}") from None
    if not np.isfinite(number):
        raise ConfigError(f"robot config: '{dotted}' must be finite")
    if positive and number <= 0:
        raise ConfigError(f"robot config: '{dotted}' must be > 0, got {number}")
    if nonneg and number < 0:
        raise ConfigError(f"robot config: '{dotted}' must be >= 0, got {number}")
    return number


def _vector(tree: dict, dotted: str, length: int) -> np.ndarray:
    value = _get(tree, dotted)
    arr = np.asarray(value, dtype=float) if isinstance(value, list) else None
    if arr is None or arr.shape != (length,) or not np.isfinite(arr).all():
        raise ConfigError(f"robot config: '{dotted}' must be a list of {length} finite numbers")
    return arr


def _hinges(tree: dict, which: str) -> np.ndarray:
    radius = _number(tree, f"geometry.{which}.radius_m", positive=True)
    angles = np.radians(_vector(tree, f"geometry.{which}.angles_deg", 6))
    z = _number(tree, f"geometry.{which}.z_m")
    return np.stack([radius * np.cos(angles), radius * np.sin(angles), np.full(6, z)], axis=1)


def _body(tree: dict, key: str) -> RigidBody:
    mass = _number(tree, f"inertia.{key}.mass_kg", positive=True)
    com = _vector(tree, f"inertia.{key}.com_m", 3)
    moments = _vector(tree, f"inertia.{key}.inertia_kg_m2", 3)
    if (moments <= 0).any():
        raise ConfigError(f"robot config: 'inertia.{key}.inertia_kg_m2' must be > 0")
    return RigidBody(mass, com, np.diag(moments))


def robot_from_dict(tree: dict, source: str = "<dict>") -> Robot:
    """Build a Robot from the parsed YAML tree (see config/robot.yaml)."""
    if not isinstance(tree, dict):
        raise ConfigError(f"robot config {source}: top level must be a mapping")
    base = _hinges(tree, "base")
    platform = _hinges(tree, "platform")
    limits = Limits(
        stroke_min=_number(tree, "limits.stroke_min_m", positive=True),
        stroke_max=_number(tree, "limits.stroke_max_m", positive=True),
        strut_velocity_max=_number(tree, "limits.strut_velocity_max_m_s", positive=True),
        strut_acceleration_max=_number(tree, "limits.strut_acceleration_max_m_s2", positive=True),
        strut_force_max=_number(tree, "limits.strut_force_max_n", positive=True),
        universal_joint_max=np.radians(_number(tree, "limits.universal_joint_max_deg", positive=True)),
        spherical_joint_max=np.radians(_number(tree, "limits.spherical_joint_max_deg", positive=True)),
        condition_number_max=_number(tree, "limits.condition_number_max", positive=True),
    )
    if limits.stroke_min >= limits.stroke_max:
        raise ConfigError("robot config: stroke_min_m must be < stroke_max_m")
    vib = VibrationUnitLimits(
        amplitude_max=_number(tree, "vibration_unit.amplitude_max_m", positive=True),
        frequency_min=_number(tree, "vibration_unit.frequency_min_hz", positive=True),
        frequency_max=_number(tree, "vibration_unit.frequency_max_hz", positive=True),
        acceleration_max=_number(tree, "vibration_unit.acceleration_max_g", positive=True)
        * STANDARD_GRAVITY,
        velocity_max=_number(tree, "vibration_unit.velocity_max_m_s", positive=True),
    )
    if vib.frequency_min >= vib.frequency_max:
        raise ConfigError("robot config: frequency_min_hz must be < frequency_max_hz")
    leg = LegInertia(
        cylinder_mass=_number(tree, "inertia.cylinder.mass_kg", nonneg=True),
        cylinder_com_offset=_number(tree, "inertia.cylinder.com_from_base_hinge_m", nonneg=True),
        cylinder_inertia_transverse=_number(tree, "inertia.cylinder.transverse_inertia_kg_m2", nonneg=True),
        cylinder_inertia_axial=_number(tree, "inertia.cylinder.axial_inertia_kg_m2", nonneg=True),
        piston_mass=_number(tree, "inertia.piston.mass_kg", nonneg=True),
        piston_com_offset=_number(tree, "inertia.piston.com_from_platform_hinge_m", nonneg=True),
        piston_inertia_transverse=_number(tree, "inertia.piston.transverse_inertia_kg_m2", nonneg=True),
        piston_inertia_axial=_number(tree, "inertia.piston.axial_inertia_kg_m2", nonneg=True),
        vibration_unit_mass=_number(tree, "inertia.vibration_unit.mass_kg", nonneg=True),
    )
    home = _vector(tree, "geometry.home_pose", 6)
    if home[2] <= 0:
        raise ConfigError("robot config: geometry.home_pose z must be > 0 (platform above base)")
    return Robot(
        base_hinges=base,
        platform_hinges=platform,
        home_pose=home,
        limits=limits,
        vibration_unit=vib,
        platform=_body(tree, "platform"),
        payload=_body(tree, "payload"),
        leg=leg,
        gravity=_vector(tree, "gravity_m_s2", 3),
        source=source,
        characteristic_length=float(np.linalg.norm(platform[:, :2], axis=1).mean()),
    )


def load_robot(path: str | os.PathLike | None = None) -> Robot:
    """Load the robot from a YAML file (default: config/robot.yaml).

    Raises ConfigError on a missing file, bad YAML, or a missing/invalid field.
    """
    path = Path(path) if path is not None else default_config_dir() / "robot.yaml"
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(f"cannot read robot config {path}: {exc}") from None
    try:
        tree = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"robot config {path}: invalid YAML ({exc})") from None
    return robot_from_dict(tree, str(path))
