"""The hardware emulator's own messages from their core values: robot_markers (visualization_msgs/MarkerArray)
of a visualization.robot_outline.RobotOutline and legs/trajectory_status (LegTrajectoryStatus) of an
emulation.command_intake.LegTrajectoryAnswer. Stamps in s of the emulator's clock."""

from __future__ import annotations

from geometry_msgs.msg import Point
from visualization_msgs.msg import Marker, MarkerArray

from stewart_vibration_interfaces.msg import LegTrajectoryStatus

from ..emulation.command_intake import LegTrajectoryAnswer
from ..messages.cdr import stamp_parts
from ..messages.fields import BASE_FRAME
from ..visualization.robot_outline import RobotOutline
from .message_conversions import time_message
from .outcomes import outcome, outcome_of


def _marker(ns: str, marker_id: int, kind: int, width: float, rgb: tuple[float, float, float], points,
            stamp: tuple[int, int]) -> Marker:
    """One opaque marker in base; ``width``: line width (lines use scale.x only) or sphere diameter (m)."""
    m = Marker(ns=ns, id=marker_id, type=kind, action=Marker.ADD)
    m.header.frame_id = BASE_FRAME
    m.header.stamp.sec, m.header.stamp.nanosec = stamp
    m.scale.x = m.scale.y = m.scale.z = width
    m.color.r, m.color.g, m.color.b, m.color.a = (*rgb, 1.0)
    m.points = [Point(x=float(p[0]), y=float(p[1]), z=float(p[2])) for p in points]
    return m


def robot_markers_msg(outline: RobotOutline, stamp_s: float) -> MarkerArray:
    """robot_markers at ``stamp_s`` (s), all in base (no /tf needed; the recorder records them, so a run's MCAP
    shows the robot in Foxglove's 3D panel): the legs, the platform and base hinge polygons, every hinge as a
    sphere."""
    stamp = stamp_parts(stamp_s)
    return MarkerArray(markers=[
        _marker("legs", 0, Marker.LINE_LIST, 0.006, (0.2, 0.5, 0.9), outline.legs, stamp),
        _marker("platform", 1, Marker.LINE_STRIP, 0.004, (0.9, 0.5, 0.1), outline.platform, stamp),
        _marker("base", 2, Marker.LINE_STRIP, 0.004, (0.55, 0.57, 0.6), outline.base, stamp),
        _marker("hinges", 3, Marker.SPHERE_LIST, 0.012, (0.25, 0.25, 0.28), outline.hinges, stamp),
    ])


def leg_trajectory_status_msg(answer: LegTrajectoryAnswer) -> LegTrajectoryStatus:
    """The LegTrajectoryStatus of ``answer``, stamped with its time (s of the emulator's clock)."""
    msg = LegTrajectoryStatus(seq=answer.seq, accepted=answer.accepted, points=answer.points,
                              end_time_s=float(answer.end_time_s))
    msg.final_positions = answer.final_positions
    msg.outcome = outcome("SUCCEEDED", "taken") if answer.error is None else outcome_of(answer.error)
    msg.header.stamp = time_message(answer.stamp_s)
    return msg
