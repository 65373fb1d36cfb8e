"""Conversions between ROS messages and the core's arrays: poses (geometry_msgs Pose / PoseStamped and
[x, y, z, roll, pitch, yaw] in m and rad, base frame unless told), durations and stamps (builtin_interfaces
and s), named values and the leg_* / vib_* columns of a JointState, the struts' JointTrajectory; and the
batching of raw 500 Hz messages and the emulator's time as a node knows it (sim s)."""

from __future__ import annotations

import time

import numpy as np
from builtin_interfaces.msg import Duration as DurationMsg
from builtin_interfaces.msg import Time as TimeMsg
from geometry_msgs.msg import PoseStamped
from rclpy.clock import Clock, ClockType
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from ..kinematics.rotations import (
    MESSAGE_QUATERNION_TOLERANCE,
    pose_from_position_quaternion,
    pose_to_position_quaternion,
)
from ..messages.cdr import stamp_parts
from ..messages.fields import BASE_FRAME
from ..robot import LEG_NAMES, VIB_NAMES


def pose_from_msg(msg) -> np.ndarray:
    """geometry_msgs/Pose -> pose [x, y, z, roll, pitch, yaw]; the quaternion is normalised if its norm is
    within 1e-3 of 1 (hand-typed input), InvalidInputError on NaN or a quaternion further off."""
    p, q = msg.position, msg.orientation
    return pose_from_position_quaternion([p.x, p.y, p.z], [q.x, q.y, q.z, q.w],
                                         unit_tolerance=MESSAGE_QUATERNION_TOLERANCE)


def pose_stamped(pose, stamp, frame_id: str = BASE_FRAME) -> PoseStamped:
    """Pose vector -> geometry_msgs/PoseStamped in ``frame_id``."""
    position, quat = pose_to_position_quaternion(pose)
    msg = PoseStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (float(v) for v in position)
    o = msg.pose.orientation
    o.x, o.y, o.z, o.w = (float(v) for v in quat)
    return msg


def named_values(names, values, wanted) -> np.ndarray | None:
    """Values for ``wanted`` names (in that order) from parallel name/value lists, None if any is missing."""
    index = {name: i for i, name in enumerate(names)}
    if len(values) < len(names) or any(name not in index for name in wanted):
        return None
    return np.array([values[index[name]] for name in wanted], dtype=float)


def emulator_now(node, state_time: float | None, fallback: float = 0.0) -> float:
    """The emulator's time as best known to ``node`` (s): on sim time the newer of /clock and the newest joint
    state's stamp ``state_time`` (a node may lag behind its input under load; /clock arrives unbatched), else
    ``state_time`` (``fallback`` before any state)."""
    now = state_time if state_time is not None else fallback
    clock = node.get_clock()
    if clock.ros_time_is_active:  # use_sim_time: the clock follows /clock (no parameter lookup per call)
        now = max(now, clock.now().nanoseconds * 1e-9)
    return now


class RawBatcher:
    """Raw messages queued by a subscription callback and handed to ``handler(messages, arrival_times)`` in
    batches: as soon as ``batch_size`` have queued (the emulator publishes its 500 Hz states in bursts of
    pace_period / state period, 10 by default, so a burst is processed the moment it is complete), and on a
    wall-clock timer every ``period_s`` for whatever is left. Batches amortise the per-call cost of the
    vectorised core; arrival times (time.monotonic) give the processing lag."""

    def __init__(self, node, batch_size: int, period_s: float, handler):
        self.batch_size, self.handler = int(batch_size), handler
        self.pending: list[bytes] = []
        self.arrivals: list[float] = []
        node.create_timer(period_s, self.flush, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def add(self, data: bytes) -> None:
        self.pending.append(data)
        self.arrivals.append(time.monotonic())
        if len(self.pending) >= self.batch_size:
            self.flush()

    def flush(self) -> None:
        if not self.pending:
            return
        messages, arrivals = self.pending, np.array(self.arrivals)
        self.pending, self.arrivals = [], []
        self.handler(messages, arrivals)


class JointColumns:
    """Column indices of leg_1..6 and of vib_1..6 in a JointState's names: (legs, vib), each an index
    array or None when a name is missing; both None when a name repeats (which column would it be?). Cached
    per name tuple (a stream repeats its names; at most MAX_LAYOUTS are kept, a fuzzer sends many)."""

    MAX_LAYOUTS = 64

    def __init__(self):
        self._cache = {}

    def __call__(self, names: tuple):
        if names not in self._cache:
            if len(self._cache) >= self.MAX_LAYOUTS:
                self._cache.clear()
            index = {n: i for i, n in enumerate(names)}
            if len(index) != len(names):
                self._cache[names] = (None, None)
                return self._cache[names]

            def find(wanted):
                return np.array([index[n] for n in wanted]) if all(n in index for n in wanted) else None

            self._cache[names] = (find(LEG_NAMES), find(VIB_NAMES))
        return self._cache[names]


def duration_msg(seconds: float) -> DurationMsg:
    """builtin_interfaces/Duration of ``seconds`` (s), rounded to the nanosecond."""
    sec, nanosec = divmod(int(round(seconds * 1e9)), 1_000_000_000)  # 0.9999999999 -> 1 s, not 0 s
    return DurationMsg(sec=sec, nanosec=nanosec)


def leg_trajectory_msg(times, positions, velocities, accelerations) -> JointTrajectory:
    """trajectory_msgs/JointTrajectory of the struts (leg_1..6) from its points: times [n] (s from the start),
    positions [n, 6] (m), velocities [n, 6] (m/s), accelerations [n, 6] (m/s^2). Stamp 0: the robot starts it
    when it arrives (the joint_trajectory_controller rule)."""
    msg = JointTrajectory()
    msg.header.stamp.sec, msg.header.stamp.nanosec = 0, 0
    msg.joint_names = list(LEG_NAMES)
    for t, position, velocity, acceleration in zip(times, positions, velocities, accelerations, strict=True):
        msg.points.append(JointTrajectoryPoint(positions=np.asarray(position, float).tolist(),
                                               velocities=np.asarray(velocity, float).tolist(),
                                               accelerations=np.asarray(acceleration, float).tolist(),
                                               time_from_start=duration_msg(float(t))))
    return msg


def duration_seconds(msg) -> float:
    """Seconds of a builtin_interfaces/Duration."""
    return msg.sec + msg.nanosec * 1e-9


def stamp_seconds(stamp) -> float:
    """Seconds of a builtin_interfaces/Time stamp."""
    return stamp.sec + stamp.nanosec * 1e-9


def time_message(seconds: float) -> TimeMsg:
    """builtin_interfaces/Time of ``seconds`` (s)."""
    sec, nanosec = stamp_parts(seconds)
    return TimeMsg(sec=sec, nanosec=nanosec)


__all__ = [
    "pose_from_msg",
    "pose_stamped",
    "named_values",
    "emulator_now",
    "RawBatcher",
    "JointColumns",
    "duration_msg",
    "leg_trajectory_msg",
    "duration_seconds",
    "stamp_seconds",
    "time_message",
]
