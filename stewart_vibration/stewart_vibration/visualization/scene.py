"""The robot's 3D scene as plain data: frame transforms and entities (pure: no rclpy, no Foxglove).

The Foxglove bridge (``nodes/foxglove_bridge_node.py``) turns a :class:`Scene` into Foxglove's
``FrameTransforms`` and ``SceneUpdate`` messages; the offline renderer (``visualization.render``)
draws the same scene with matplotlib. Everything is in SI units, quaternions are [x, y, z, w].

Frames (every one a child of the root ``base``):

- ``platform``: the platform pose (origin at the platform hinge-circle centre), exactly the
  position and quaternion it was built from;
- ``leg_1`` .. ``leg_6``: origin at base hinge B_i, z along the leg toward platform hinge A_i
  (x and y by the shortest rotation from base z), so the leg spans z = 0 .. L_i.

Entities (id: frame):

- ``base`` (base): the base ring (hinge circle) and the base hinges (universal joints) as spheres;
- ``platform`` (platform): the platform ring and the platform hinges (spherical joints);
- ``leg_i`` (leg_i): two cylinders, the strut's cylinder from the base hinge and its piston ending
  at the platform hinge (lengths from the robot's leg inertia data, clipped to the leg);
- ``vibration_direction`` (base), only when a direction is given: an arrow from the platform origin
  along the planned platform vibration direction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kinematics import jacobian_from_vectors
from ..kinematics.rotations import rotation_from_quaternion
from ..robot import LEG_NAMES, Robot

Color = tuple[float, float, float, float]

BASE_FRAME = "base"
PLATFORM_FRAME = "platform"
LEG_FRAMES = LEG_NAMES  # a TF frame per leg, named as its strut joint
VIBRATION_ENTITY = "vibration_direction"
STATIC_ENTITIES = ("base", "platform")  # never change in their frames

# Look (m, RGBA); one place, shared by the bridge and the renderer.
CYLINDER_DIAMETER = 0.016
PISTON_DIAMETER = 0.009
HINGE_DIAMETER = 0.014
RING_THICKNESS = 0.005
RING_POINTS = 72
ARROW_LENGTH = 0.06
BASE_COLOR: Color = (0.55, 0.57, 0.60, 1.0)
PLATFORM_COLOR: Color = (0.95, 0.55, 0.15, 1.0)
HINGE_COLOR: Color = (0.25, 0.25, 0.28, 1.0)
CYLINDER_COLOR: Color = (0.20, 0.45, 0.85, 1.0)
PISTON_COLOR: Color = (0.70, 0.80, 0.95, 1.0)
ARROW_COLOR: Color = (0.90, 0.10, 0.15, 1.0)


@dataclass(frozen=True)
class FrameTransform:
    """Pose of frame ``child`` in frame ``parent``: a point x in child maps to R(rotation) x + translation."""

    parent: str
    child: str
    translation: np.ndarray  # (3,) m
    rotation: np.ndarray  # (4,) [x, y, z, w]


@dataclass(frozen=True)
class Cylinder:
    """Axis along the local z of ``orientation``, centred at ``position``; size = (diameter x, diameter y, length)."""

    position: np.ndarray
    orientation: np.ndarray
    size: np.ndarray
    color: Color


@dataclass(frozen=True)
class Sphere:
    """A sphere of ``diameter`` (m) centred at ``position`` (3,) m in its entity's frame."""

    position: np.ndarray
    diameter: float
    color: Color


@dataclass(frozen=True)
class Line:
    """Polyline through ``points`` (n, 3); ``closed``: back to the first point (a loop)."""

    points: np.ndarray
    thickness: float
    color: Color
    closed: bool = False


@dataclass(frozen=True)
class Arrow:
    """Tail at ``position``, pointing along ``direction`` (unit); Foxglove's arrow points along the local x
    of ``orientation`` (= quaternion_between(x, direction))."""

    position: np.ndarray
    direction: np.ndarray
    orientation: np.ndarray
    shaft_length: float
    shaft_diameter: float
    head_length: float
    head_diameter: float
    color: Color


@dataclass(frozen=True)
class Entity:
    """Primitives drawn in frame ``frame_id`` (positions in that frame, m), named ``id``."""

    id: str
    frame_id: str
    cylinders: tuple[Cylinder, ...] = ()
    spheres: tuple[Sphere, ...] = ()
    lines: tuple[Line, ...] = ()
    arrows: tuple[Arrow, ...] = ()


@dataclass(frozen=True)
class Scene:
    """Transforms and entities at time ``stamp`` (s, the pose's clock)."""

    stamp: float
    transforms: tuple[FrameTransform, ...]
    entities: tuple[Entity, ...]

    def transform(self, child: str) -> FrameTransform:
        """The transform of frame ``child`` (base -> child); StopIteration if the scene has none."""
        return next(t for t in self.transforms if t.child == child)

    def entity(self, entity_id: str) -> Entity | None:
        """The entity ``entity_id``, or None if the scene has none."""
        return next((e for e in self.entities if e.id == entity_id), None)

    def to_base(self, frame_id: str, points) -> np.ndarray:
        """Points (..., 3) given in ``frame_id`` -> base frame (every frame here is a child of base)."""
        points = np.asarray(points, dtype=float)
        if frame_id == BASE_FRAME:
            return points
        t = self.transform(frame_id)
        return points @ rotation_from_quaternion(t.rotation).T + t.translation


def quaternion_between(a, b) -> np.ndarray:
    """Unit quaternion [x, y, z, w] of the shortest rotation taking direction ``a`` to direction ``b``."""
    a = np.asarray(a, dtype=float) / np.linalg.norm(a)
    b = np.asarray(b, dtype=float) / np.linalg.norm(b)
    w = 1.0 + float(a @ b)
    if w < 1e-12:  # opposite: half a turn about any axis normal to a
        axis = np.cross(a, [1.0, 0.0, 0.0])
        if np.linalg.norm(axis) < 1e-6:
            axis = np.cross(a, [0.0, 1.0, 0.0])
        axis /= np.linalg.norm(axis)
        return np.array([axis[0], axis[1], axis[2], 0.0])
    q = np.array([*np.cross(a, b), w])
    return q / np.linalg.norm(q)


def _z_to(directions: np.ndarray) -> np.ndarray:
    """quaternion_between(z, d) for rows d (n, 3) at once (z x d = (-d_y, d_x, 0), w = 1 + z . d)."""
    d = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    q = np.column_stack([-d[:, 1], d[:, 0], np.zeros(len(d)), 1.0 + d[:, 2]])
    with np.errstate(invalid="ignore", divide="ignore"):  # straight down: 0 / 0, replaced below
        q /= np.linalg.norm(q, axis=1, keepdims=True)
    for i in np.flatnonzero(1.0 + d[:, 2] < 1e-12):  # straight down: no shortest rotation, any half turn
        q[i] = quaternion_between([0.0, 0.0, 1.0], d[i])
    return q


def _ring(hinges: np.ndarray) -> np.ndarray:
    """Circle through the hinge circle (radius: mean distance of the hinges from the z axis)."""
    radius = float(np.mean(np.hypot(hinges[:, 0], hinges[:, 1])))
    angles = np.linspace(0.0, 2 * np.pi, RING_POINTS, endpoint=False)
    return np.column_stack([radius * np.cos(angles), radius * np.sin(angles),
                            np.full(RING_POINTS, float(np.mean(hinges[:, 2])))])


def _hinge_entity(entity_id: str, frame: str, hinges: np.ndarray, ring_color: Color) -> Entity:
    return Entity(
        id=entity_id, frame_id=frame,
        spheres=tuple(Sphere(h.copy(), HINGE_DIAMETER, HINGE_COLOR) for h in hinges),
        lines=(Line(_ring(hinges), RING_THICKNESS, ring_color, closed=True),),
    )


_NO_ROTATION = np.array([0.0, 0.0, 0.0, 1.0])


def _z_cylinder(z0: float, z1: float, diameter: float, color: Color) -> Cylinder:
    """Cylinder along the leg frame's z from z0 to z1."""
    return Cylinder(np.array([0.0, 0.0, (z0 + z1) / 2]), _NO_ROTATION, np.array([diameter, diameter, z1 - z0]), color)


class SceneBuilder:
    """Scenes of one robot; the entities that never change in their frame (``STATIC_ENTITIES``: the base
    and the platform with their rings and hinges) are built once and shared by every scene."""

    def __init__(self, robot: Robot):
        self.robot = robot
        self.static = (_hinge_entity("base", BASE_FRAME, robot.base_hinges, BASE_COLOR),
                       _hinge_entity("platform", PLATFORM_FRAME, robot.platform_hinges, PLATFORM_COLOR))
        self._cylinder_len = 2 * robot.leg.cylinder_com_offset
        self._piston_len = 2 * robot.leg.piston_com_offset

    def scene(self, position, quaternion, stamp: float = 0.0, vibration_direction=None) -> Scene:
        """The scene at platform pose (position (3,) m, unit quaternion (4,) [x, y, z, w], both in base).

        ``vibration_direction`` (3,) in base, any length > 0, or None (no arrow).
        """
        robot = self.robot
        position = np.asarray(position, dtype=float).reshape(3)
        quaternion = np.asarray(quaternion, dtype=float).reshape(4)
        tips = position + robot.platform_hinges @ rotation_from_quaternion(quaternion).T  # A_i in base
        legs = tips - robot.base_hinges
        lengths = np.linalg.norm(legs, axis=1)
        rotations = _z_to(legs)
        transforms = [FrameTransform(BASE_FRAME, PLATFORM_FRAME, position.copy(), quaternion.copy())]
        entities = list(self.static)
        for i, frame in enumerate(LEG_FRAMES):
            length = float(lengths[i])
            transforms.append(FrameTransform(BASE_FRAME, frame, robot.base_hinges[i].copy(), rotations[i]))
            entities.append(Entity(id=frame, frame_id=frame, cylinders=(
                _z_cylinder(0.0, min(self._cylinder_len, length), CYLINDER_DIAMETER, CYLINDER_COLOR),
                _z_cylinder(max(length - self._piston_len, 0.0), length, PISTON_DIAMETER, PISTON_COLOR),
            )))
        if vibration_direction is not None:
            u = np.asarray(vibration_direction, dtype=float).reshape(3)
            u = u / np.linalg.norm(u)
            entities.append(Entity(id=VIBRATION_ENTITY, frame_id=BASE_FRAME, arrows=(Arrow(
                position.copy(), u, quaternion_between([1, 0, 0], u), shaft_length=ARROW_LENGTH * 0.75,
                shaft_diameter=0.004, head_length=ARROW_LENGTH * 0.25, head_diameter=0.010, color=ARROW_COLOR),)))
        return Scene(float(stamp), tuple(transforms), tuple(entities))


def robot_scene(robot: Robot, position, quaternion, stamp: float = 0.0, vibration_direction=None) -> Scene:
    """The scene at one platform pose (see SceneBuilder.scene; a builder saves the static part per call)."""
    return SceneBuilder(robot).scene(position, quaternion, stamp, vibration_direction)


def vibration_direction_from_window(robot: Robot, position, quaternion, vib_positions) -> np.ndarray | None:
    """Platform vibration direction (unit, base frame) of a vibration command, or None if it has none.

    ``vib_positions`` (n, 6): samples of vib_1..vib_6 (m), e.g. one vibration/joint_trajectory window.
    The legs of a line vibration move as e(t) g with one gain vector g (the first right singular vector
    of the samples); the platform moves by J^-1 g at the pose (J: leg-length Jacobian). The direction is
    its translation, signed toward the platform's +z side (a vibration along a line has no sign).
    """
    vib = np.asarray(vib_positions, dtype=float)
    if vib.ndim != 2 or vib.shape[1] != 6 or len(vib) < 2 or not np.isfinite(vib).all():
        return None
    _, singular, vt = np.linalg.svd(vib, full_matrices=False)
    if singular[0] <= 1e-12:  # no motion (below a picometre)
        return None
    rot = rotation_from_quaternion(np.asarray(quaternion, dtype=float))
    arms = robot.platform_hinges @ rot.T
    legs = np.asarray(position, dtype=float) + arms - robot.base_hinges
    try:
        motion = np.linalg.solve(jacobian_from_vectors(legs, arms), vt[0])
    except np.linalg.LinAlgError:
        return None
    translation = motion[:3]
    norm = np.linalg.norm(translation)
    if not np.isfinite(norm) or norm == 0:
        return None
    u = translation / norm
    return -u if u @ rot[:, 2] < 0 else u


__all__ = [
    "ARROW_LENGTH",
    "BASE_FRAME",
    "LEG_FRAMES",
    "PLATFORM_FRAME",
    "STATIC_ENTITIES",
    "VIBRATION_ENTITY",
    "Arrow",
    "Cylinder",
    "Entity",
    "FrameTransform",
    "Line",
    "Scene",
    "SceneBuilder",
    "Sphere",
    "quaternion_between",
    "robot_scene",
    "vibration_direction_from_window",
]
