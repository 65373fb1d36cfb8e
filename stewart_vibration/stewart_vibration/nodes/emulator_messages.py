"""The hardware emulator's own messages from their core values: one state period's streams as serialized CDR
(of an emulation.physics_thread.Block) and their publishers, robot_markers (visualization_msgs/MarkerArray) of a
visualization.robot_outline.RobotOutline and legs/trajectory_status (LegTrajectoryStatus) of an
emulation.command_intake.LegTrajectoryAnswer. Stamps in s of the emulator's clock."""

from __future__ import annotations

from dataclasses import dataclass, field

from geometry_msgs.msg import Point
from rclpy.publisher import Publisher
from visualization_msgs.msg import Marker, MarkerArray

from stewart_vibration_interfaces.msg import LegTrajectoryStatus

from ..emulation.command_intake import LegTrajectoryAnswer
from ..emulation.physics_thread import Block
from ..messages import joint_states, stamped_doubles
from ..messages.cdr import encode_clock, stamp_parts
from ..messages.fields import BASE_FRAME, PLATFORM_FRAME
from ..robot import LEG_NAMES, VIB_NAMES
from ..visualization.robot_outline import RobotOutline
from .message_conversions import time_message
from .outcomes import outcome, outcome_of


@dataclass(frozen=True)
class StatePeriodBytes:
    """One state period's messages, serialized: /clock (None when not due), the sensors (legs/joint_states,
    platform/imu, the platform/tracker_pose frames due) and the truth (ground_truth/joint_states,
    ground_truth/platform_pose, ground_truth/tissue_wrench: None without tissue)."""

    clock: bytes | None
    joint_states: bytes
    imu: bytes
    tracker_poses: list[bytes]
    true_joint_states: bytes
    true_pose: bytes
    tissue_wrench: bytes | None


class StatePeriodEncoder:
    """Serializes state periods for the 500 Hz streams (each encoder fills in a message template built once)."""

    def __init__(self) -> None:
        self.joint_states = joint_states.JointStateEncoder(LEG_NAMES + VIB_NAMES)
        self.poses = stamped_doubles.PoseStampedEncoder(BASE_FRAME)
        self.wrenches = stamped_doubles.WrenchStampedEncoder(BASE_FRAME)
        self.imu = stamped_doubles.ImuEncoder(PLATFORM_FRAME)

    def encode(self, block: Block, tissue: bool) -> StatePeriodBytes:
        """The messages of ``block``, stamped with its time; the tissue wrench only if ``tissue``."""
        now = block.time
        sensed, imu, frames = block.sensors
        _, positions, velocities, efforts = sensed
        sensed_cdr = self.joint_states.encode(now, positions, velocities, efforts)
        true_state, position, quaternion, wrench = block.truth
        if true_state is sensed:  # the ideal plant: its sensors are the truth, the same bytes
            true_cdr = sensed_cdr
        else:
            _, positions, velocities, efforts = true_state
            true_cdr = self.joint_states.encode(now, positions, velocities, efforts)
        return StatePeriodBytes(
            clock=encode_clock(now) if block.clock_due else None, joint_states=sensed_cdr,
            imu=self.imu.encode(now, imu.angular_velocity, imu.linear_acceleration, imu.gyro_variance,
                                imu.accel_variance),
            tracker_poses=[self.poses.encode(frame.stamp, frame.position, frame.quaternion) for frame in frames],
            true_joint_states=true_cdr, true_pose=self.poses.encode(now, position, quaternion),
            tissue_wrench=self.wrenches.encode(now, wrench) if tissue else None)


@dataclass(frozen=True)
class StateStreams:
    """The publishers of the state streams (the node creates them) and the encoder that fills them; ``tissue``
    is None without a tissue model."""

    clock: Publisher
    joint_states: Publisher
    imu: Publisher
    tracker: Publisher
    true_joint_states: Publisher
    true_pose: Publisher
    tissue: Publisher | None = None
    encoder: StatePeriodEncoder = field(default_factory=StatePeriodEncoder)

    def publish(self, block: Block) -> None:
        """One state period: /clock when due, the sensors, the truth."""
        out = self.encoder.encode(block, tissue=self.tissue is not None)
        if out.clock is not None:
            self.clock.publish(out.clock)
        self.joint_states.publish(out.joint_states)
        self.imu.publish(out.imu)
        for pose in out.tracker_poses:
            self.tracker.publish(pose)
        self.true_joint_states.publish(out.true_joint_states)
        self.true_pose.publish(out.true_pose)
        if self.tissue is not None:
            self.tissue.publish(out.tissue_wrench)

    def publishers(self) -> list:
        """Every publisher (to destroy them at cleanup)."""
        return [pub for pub in (self.clock, self.joint_states, self.imu, self.tracker, self.true_joint_states,
                                self.true_pose, self.tissue) if pub is not None]


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
