"""The robot scene (``visualization.scene``: plain data) as Foxglove schema objects (foxglove-sdk, no rclpy):
what the Foxglove bridge sends on its scene channels."""

from __future__ import annotations

from foxglove.schemas import (
    ArrowPrimitive,
    Color,
    CylinderPrimitive,
    FrameTransform,
    FrameTransforms,
    LinePrimitive,
    LinePrimitiveLineType,
    Point3,
    Pose,
    Quaternion,
    SceneEntity,
    SpherePrimitive,
    Timestamp,
    Vector3,
)

from ..messages import cdr
from . import scene as scene_model


def foxglove_timestamp(seconds: float) -> Timestamp:
    """A stamp in s as a Foxglove Timestamp."""
    sec, nanosec = cdr.stamp_parts(seconds)
    return Timestamp(sec, nanosec)


def _vector(v) -> Vector3:
    return Vector3(x=float(v[0]), y=float(v[1]), z=float(v[2]))


def _quaternion(q) -> Quaternion:
    return Quaternion(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3]))


def _pose(position, orientation) -> Pose:
    return Pose(position=_vector(position), orientation=_quaternion(orientation))


def _color(c) -> Color:
    return Color(r=c[0], g=c[1], b=c[2], a=c[3])


IDENTITY = (0.0, 0.0, 0.0, 1.0)


def foxglove_transforms(scene: scene_model.Scene) -> FrameTransforms:
    """The scene's transforms (base -> platform -> legs) as one FrameTransforms message."""
    stamp = foxglove_timestamp(scene.stamp)
    return FrameTransforms(transforms=[
        FrameTransform(timestamp=stamp, parent_frame_id=t.parent, child_frame_id=t.child,
                       translation=_vector(t.translation), rotation=_quaternion(t.rotation))
        for t in scene.transforms])


def foxglove_entities(stamp_s: float, entities) -> list[SceneEntity]:
    """Scene entities (cylinders, spheres, lines, arrows; visualization.scene) as Foxglove SceneEntity objects
    stamped ``stamp_s`` (s)."""
    stamp = foxglove_timestamp(stamp_s)
    return [SceneEntity(
        timestamp=stamp, frame_id=e.frame_id, id=e.id, frame_locked=True,
        cylinders=[CylinderPrimitive(pose=_pose(c.position, c.orientation), size=_vector(c.size),
                                     bottom_scale=1.0, top_scale=1.0, color=_color(c.color)) for c in e.cylinders],
        spheres=[SpherePrimitive(pose=_pose(s.position, IDENTITY), size=_vector([s.diameter] * 3),
                                 color=_color(s.color)) for s in e.spheres],
        lines=[LinePrimitive(type=LinePrimitiveLineType.LineLoop if line.closed else LinePrimitiveLineType.LineStrip,
                             pose=_pose((0, 0, 0), IDENTITY), thickness=line.thickness, scale_invariant=False,
                             points=[Point3(x=float(p[0]), y=float(p[1]), z=float(p[2])) for p in line.points],
                             color=_color(line.color)) for line in e.lines],
        arrows=[ArrowPrimitive(pose=_pose(a.position, a.orientation), shaft_length=a.shaft_length,
                               shaft_diameter=a.shaft_diameter, head_length=a.head_length,
                               head_diameter=a.head_diameter, color=_color(a.color)) for a in e.arrows],
    ) for e in entities]
