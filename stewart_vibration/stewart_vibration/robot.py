"""Robot description from config/robot.yaml (the single source of truth): the Robot and its field checks.

``kinematics.robot_config.load_robot`` reads the file (``stewart_vibration.load_robot``); ``robot_from_dict``
here builds the Robot from the parsed tree, every value checked against its plausible range.

Frames: ``base`` (origin at the base hinge-circle centre, z toward the
platform) and ``platform`` (origin at the platform hinge-circle centre).
"""

from __future__ import annotations

import copy
import weakref
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from typing import Any, TypeVar

import numpy as np

from .config_values import Plausible, as_number, as_vector, lookup
from .errors import ConfigError

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
    frame; strut_zero_offsets (6,) m: what each strut's encoder reads short of its hinge-to-hinge length
    (encoder = length - offset; zero for the drawing, identified by a kinematic calibration);
    load_cell_offsets (6,) N: what each leg's load cell reads beyond the axial force (a calibration's). The arrays
    are read-only. Two robots are equal only if they are the same object (constants
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
    strut_zero_offsets: np.ndarray = field(default_factory=lambda: np.zeros(6))
    load_cell_offsets: np.ndarray = field(default_factory=lambda: np.zeros(6))
    calibrated: bool = False  # the file carries a calibration's corrections (not the drawing)
    source: str = ""
    characteristic_length: float = field(default=0.0)

    def __post_init__(self):
        for f in fields(self):
            if f.name in ("base_hinges", "platform_hinges", "home_pose", "gravity", "strut_zero_offsets",
                          "load_cell_offsets"):
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


# Plausible ranges of robot.yaml's values (SI unless the key says otherwise): wide enough for any bench
# or clinical 6-UPS robot of this kind, narrow enough that a typo (a unit amplitude of 1 km, gravity of
# 1e300) is refused before any code uses it.
_LENGTH = Plausible(-1.0, 1.0, "m")
_PLAUSIBLE = {
    "geometry.base.radius_m": Plausible(0.01, 1.0, "m"),
    "geometry.platform.radius_m": Plausible(0.01, 1.0, "m"),
    "geometry.base.z_m": _LENGTH,
    "geometry.platform.z_m": _LENGTH,
    "geometry.base.angles_deg": Plausible(-360.0, 360.0, "deg"),
    "geometry.platform.angles_deg": Plausible(-360.0, 360.0, "deg"),
    "limits.stroke_min_m": Plausible(0.01, 2.0, "m"),
    "limits.stroke_max_m": Plausible(0.01, 2.0, "m"),
    "limits.strut_velocity_max_m_s": Plausible(0.0, 1.0, "m/s", low_open=True),
    "limits.strut_acceleration_max_m_s2": Plausible(0.0, 100.0, "m/s^2", low_open=True),
    "limits.strut_force_max_n": Plausible(0.0, 1e5, "N", low_open=True),
    "limits.universal_joint_max_deg": Plausible(0.0, 90.0, "deg", low_open=True),
    "limits.spherical_joint_max_deg": Plausible(0.0, 90.0, "deg", low_open=True),
    "limits.condition_number_max": Plausible(1.0, 1e4),
    "vibration_unit.amplitude_max_m": Plausible(0.0, 5e-3, "m", low_open=True),
    "vibration_unit.frequency_min_hz": Plausible(0.0, 1000.0, "Hz", low_open=True),
    "vibration_unit.frequency_max_hz": Plausible(0.0, 1000.0, "Hz", low_open=True),
    "vibration_unit.acceleration_max_g": Plausible(0.0, 10.0, "g", low_open=True),
    "vibration_unit.velocity_max_m_s": Plausible(0.0, 1.0, "m/s", low_open=True),
    "inertia.platform.mass_kg": Plausible(0.0, 100.0, "kg", low_open=True),
    "inertia.payload.mass_kg": Plausible(0.0, 100.0, "kg", low_open=True),
    "inertia.platform.com_m": _LENGTH,
    "inertia.payload.com_m": _LENGTH,
    "inertia.platform.inertia_kg_m2": Plausible(0.0, 10.0, "kg m^2", low_open=True),
    "inertia.payload.inertia_kg_m2": Plausible(0.0, 10.0, "kg m^2", low_open=True),
    "inertia.payload_identified.mass_kg": Plausible(0.0, 100.0, "kg", low_open=True),
    "inertia.payload_identified.com_m": _LENGTH,
    "inertia.payload_identified.inertia_kg_m2": Plausible(0.0, 10.0, "kg m^2", low_open=True),
    "inertia.cylinder.mass_kg": Plausible(0.0, 10.0, "kg"),
    "inertia.cylinder.com_from_base_hinge_m": Plausible(0.0, 1.0, "m"),
    "inertia.cylinder.transverse_inertia_kg_m2": Plausible(0.0, 1.0, "kg m^2"),
    "inertia.cylinder.axial_inertia_kg_m2": Plausible(0.0, 1.0, "kg m^2"),
    "inertia.piston.mass_kg": Plausible(0.0, 10.0, "kg"),
    "inertia.piston.com_from_platform_hinge_m": Plausible(0.0, 1.0, "m"),
    "inertia.piston.transverse_inertia_kg_m2": Plausible(0.0, 1.0, "kg m^2"),
    "inertia.piston.axial_inertia_kg_m2": Plausible(0.0, 1.0, "kg m^2"),
    "inertia.vibration_unit.mass_kg": Plausible(0.0, 1.0, "kg"),
    "gravity_m_s2": Plausible(-20.0, 20.0, "m/s^2"),
}
# a calibration's hinge corrections and strut zero offsets: a few tenths of a millimetre on a real fixator;
# more than 5 mm is another robot, not a calibrated drawing
CALIBRATION_CORRECTION = Plausible(-0.005, 0.005, "m")
LOAD_CELL_OFFSET = Plausible(-50.0, 50.0, "N")  # a load cell's zero: beyond this it is broken, not offset
STROKE_RANGE = Plausible(0.01, 1.0, "m")  # stroke_max_m - stroke_min_m: a few cm to a metre
GRAVITY_MAGNITUDE = Plausible(0.0, 20.0, "m/s^2")  # |gravity|: up to about 2 g


def _number(tree: dict, dotted: str, where: str) -> float:
    return as_number(lookup(tree, dotted, where), dotted, where, _PLAUSIBLE[dotted])


def _vector(tree: dict, dotted: str, length: int, where: str) -> np.ndarray:
    return as_vector(lookup(tree, dotted, where), dotted, where, length, _PLAUSIBLE.get(dotted))


def _hinges(tree: dict, which: str, where: str) -> np.ndarray:
    """The drawn hinge circle's points (6, 3) m plus the optional ``hinge_corrections_m`` (a calibration's)."""
    radius = _number(tree, f"geometry.{which}.radius_m", where)
    angles = np.radians(_vector(tree, f"geometry.{which}.angles_deg", 6, where))
    z = _number(tree, f"geometry.{which}.z_m", where)
    drawn = np.stack([radius * np.cos(angles), radius * np.sin(angles), np.full(6, z)], axis=1)
    key = f"geometry.{which}.hinge_corrections_m"
    corrections = tree["geometry"][which].get("hinge_corrections_m")
    if corrections is None:
        return drawn
    if not isinstance(corrections, list) or len(corrections) != 6:
        raise ConfigError(f"{where}: '{key}' must be a list of 6 [x, y, z] corrections (m)")
    return drawn + np.array([as_vector(row, f"{key}[{i}]", where, 3, CALIBRATION_CORRECTION)
                             for i, row in enumerate(corrections)])


def _calibrated_vector(tree: dict, section: str, key: str, where: str, plausible: Plausible) -> np.ndarray:
    """The optional ``section.key`` (6,) of a calibration, zeros without it."""
    if section in tree and not isinstance(tree[section], dict):
        raise ConfigError(f"{where}: '{section}' must be a mapping")
    if key not in tree.get(section, {}):
        return np.zeros(6)
    return as_vector(tree[section][key], f"{section}.{key}", where, 6, plausible)


def _body(tree: dict, key: str, where: str) -> RigidBody:
    mass = _number(tree, f"inertia.{key}.mass_kg", where)
    com = _vector(tree, f"inertia.{key}.com_m", 3, where)
    moments = _vector(tree, f"inertia.{key}.inertia_kg_m2", 3, where)
    if (moments.sum() - moments < moments).any():  # principal moments of a real body: each <= the other two
        raise ConfigError(f"{where}: 'inertia.{key}.inertia_kg_m2' {moments.tolist()} is not a body's inertia "
                          "(each principal moment must be at most the sum of the other two)")
    return RigidBody(mass, com, np.diag(moments))


def drawing_tree(tree: dict) -> dict:
    """A copy of a parsed robot file without any calibration (its hinge corrections, strut zero offsets,
    identified payload, load cell offsets and provenance): the drawing the calibration corrects."""
    tree = copy.deepcopy(tree)
    for key in ("calibration", "load_cells"):
        tree.pop(key, None)
    if isinstance(tree.get("inertia"), dict):
        tree["inertia"].pop("payload_identified", None)
    geometry = tree.get("geometry")
    if isinstance(geometry, dict):
        geometry.pop("strut_zero_offsets_m", None)
        for part in ("base", "platform"):
            if isinstance(geometry.get(part), dict):
                geometry[part].pop("hinge_corrections_m", None)
    return tree


def robot_from_dict(tree: dict, source: str = "<dict>") -> Robot:
    """Build a Robot from the parsed YAML tree (see config/robot.yaml), every value checked.

    Each value must be a finite number inside its plausible range (``_PLAUSIBLE``), stroke_min_m <
    stroke_max_m with a stroke of a few cm to a metre, frequency_min_hz < frequency_max_hz, |gravity| at
    most about 2 g and the home pose above the base. That the home pose can be taken (strokes, joints,
    conditioning) is checked by ``load_robot``, which needs the kinematics.

    Args:
        tree: the parsed YAML mapping.
        source: where the tree comes from, for error messages and ``Robot.source``.

    Returns:
        The Robot (SI units).

    Raises:
        ConfigError: one line naming the key: missing, wrong type, non-finite or implausible.
    """
    where = f"robot config {source}"
    if not isinstance(tree, dict):
        raise ConfigError(f"{where}: top level must be a mapping")
    for section in ("geometry", "geometry.base", "geometry.platform"):
        if not isinstance(lookup(tree, section, where), dict):
            raise ConfigError(f"{where}: '{section}' must be a mapping")
    base = _hinges(tree, "base", where)
    platform = _hinges(tree, "platform", where)
    limits = Limits(
        stroke_min=_number(tree, "limits.stroke_min_m", where),
        stroke_max=_number(tree, "limits.stroke_max_m", where),
        strut_velocity_max=_number(tree, "limits.strut_velocity_max_m_s", where),
        strut_acceleration_max=_number(tree, "limits.strut_acceleration_max_m_s2", where),
        strut_force_max=_number(tree, "limits.strut_force_max_n", where),
        universal_joint_max=np.radians(_number(tree, "limits.universal_joint_max_deg", where)),
        spherical_joint_max=np.radians(_number(tree, "limits.spherical_joint_max_deg", where)),
        condition_number_max=_number(tree, "limits.condition_number_max", where),
    )
    if limits.stroke_min >= limits.stroke_max:
        raise ConfigError(f"{where}: 'limits.stroke_min_m' {limits.stroke_min:g} must be < 'limits.stroke_max_m' "
                          f"{limits.stroke_max:g}")
    if limits.stroke_max - limits.stroke_min not in STROKE_RANGE:
        raise ConfigError(f"{where}: the stroke 'limits.stroke_max_m' - 'limits.stroke_min_m' = "
                          f"{limits.stroke_max - limits.stroke_min:g} m is outside its plausible range {STROKE_RANGE}")
    vib = VibrationUnitLimits(
        amplitude_max=_number(tree, "vibration_unit.amplitude_max_m", where),
        frequency_min=_number(tree, "vibration_unit.frequency_min_hz", where),
        frequency_max=_number(tree, "vibration_unit.frequency_max_hz", where),
        acceleration_max=_number(tree, "vibration_unit.acceleration_max_g", where) * STANDARD_GRAVITY,
        velocity_max=_number(tree, "vibration_unit.velocity_max_m_s", where),
    )
    if vib.frequency_min >= vib.frequency_max:
        raise ConfigError(f"{where}: 'vibration_unit.frequency_min_hz' {vib.frequency_min:g} must be < "
                          f"'vibration_unit.frequency_max_hz' {vib.frequency_max:g}")
    leg = LegInertia(*(_number(tree, f"inertia.{key}", where) for key in (
        "cylinder.mass_kg", "cylinder.com_from_base_hinge_m", "cylinder.transverse_inertia_kg_m2",
        "cylinder.axial_inertia_kg_m2", "piston.mass_kg", "piston.com_from_platform_hinge_m",
        "piston.transverse_inertia_kg_m2", "piston.axial_inertia_kg_m2", "vibration_unit.mass_kg")))
    home = _vector(tree, "geometry.home_pose", 6, where)
    if not home[2] > 0:
        raise ConfigError(f"{where}: 'geometry.home_pose' z must be > 0 (platform above base), got {home[2]:g}")
    gravity = _vector(tree, "gravity_m_s2", 3, where)
    if float(np.linalg.norm(gravity)) not in GRAVITY_MAGNITUDE:
        raise ConfigError(f"{where}: 'gravity_m_s2' has magnitude {np.linalg.norm(gravity):g} m/s^2, outside its "
                          f"plausible range {GRAVITY_MAGNITUDE}")
    return Robot(
        base_hinges=base,
        platform_hinges=platform,
        home_pose=home,
        limits=limits,
        vibration_unit=vib,
        platform=_body(tree, "platform", where),
        payload=_body(tree, "payload_identified" if isinstance(tree.get("inertia"), dict) and "payload_identified" in
                      tree["inertia"] else "payload", where),
        leg=leg,
        gravity=gravity,
        strut_zero_offsets=_calibrated_vector(tree, "geometry", "strut_zero_offsets_m", where, CALIBRATION_CORRECTION),
        load_cell_offsets=_calibrated_vector(tree, "load_cells", "offsets_n", where, LOAD_CELL_OFFSET),
        calibrated=drawing_tree(tree) != tree,
        source=source,
        characteristic_length=float(np.linalg.norm(platform[:, :2], axis=1).mean()),
    )
