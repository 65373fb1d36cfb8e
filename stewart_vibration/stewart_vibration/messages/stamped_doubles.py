"""Messages laid out as a std_msgs/Header and float64 fields, as raw CDR (numpy, no rclpy): geometry_msgs/
PoseStamped (position m, quaternion [x, y, z, w]), geometry_msgs/WrenchStamped (force N, torque N m) and
sensor_msgs/Imu (angular velocity rad/s, linear acceleration m/s^2, no orientation estimate). Encoders of one
fixed frame (the header's frame_id, e.g. base or platform); decoders of one message, and of a stream at once
(``decode_stamped_doubles``). Stamps in s.
"""

from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError
from .cdr import F8, NANOSEC_PER_SEC, STAMP, STAMP_DTYPE, CdrReader, CdrWriter, stamp_parts, stamp_seconds


class _HeaderDoublesEncoder:
    """A message laid out as Header (fixed frame) + float64 fields: a template, and per message its stamp and
    a writable view of the doubles."""

    def __init__(self, frame_id: str, fields):
        w = CdrWriter()
        w.stamp(0, 0)
        w.string(frame_id)
        self.count = len(fields)
        self.offset = w.fixed_doubles(fields)
        self.template = bytes(w.buf)

    def _stamped(self, stamp_s: float) -> tuple[bytearray, np.ndarray]:
        """(a copy of the template stamped ``stamp_s`` (s), the view of its doubles)."""
        buf = bytearray(self.template)
        STAMP.pack_into(buf, 4, *stamp_parts(stamp_s))
        return buf, np.frombuffer(buf, dtype=F8, count=self.count, offset=self.offset)


class PoseStampedEncoder(_HeaderDoublesEncoder):
    """PoseStamped in a fixed frame: position (3,) m and quaternion (4,) [x, y, z, w]."""

    def __init__(self, frame_id: str):
        super().__init__(frame_id, np.zeros(7))

    def encode(self, stamp_s: float, position, quaternion) -> bytes:
        """PoseStamped bytes at ``stamp_s`` (s): position (3,) m and quaternion (4,) [x, y, z, w], encoder's frame."""
        buf, values = self._stamped(stamp_s)
        values[:3], values[3:] = position, quaternion
        return bytes(buf)


def _decode_header_doubles(data, type_name: str, count: int) -> tuple[float, str, np.ndarray]:
    """(stamp s, frame_id, the ``count`` doubles after the header) of a message made of a Header and doubles."""
    r = CdrReader(data, type_name)
    sec, nanosec = r.stamp()
    frame = r.string()
    return stamp_seconds(sec, nanosec), frame, r.fixed_doubles(count)


def decode_pose_stamped(data) -> tuple[float, str, np.ndarray, np.ndarray]:
    """(stamp s, frame_id, position (3,), quaternion (4,) [x, y, z, w]) of PoseStamped bytes."""
    stamp, frame, values = _decode_header_doubles(data, "PoseStamped", 7)
    return stamp, frame, values[:3], values[3:]


class WrenchStampedEncoder(_HeaderDoublesEncoder):
    """WrenchStamped in a fixed frame: force (3,) N and torque (3,) N m."""

    def __init__(self, frame_id: str):
        super().__init__(frame_id, np.zeros(6))

    def encode(self, stamp_s: float, wrench) -> bytes:
        """WrenchStamped bytes at ``stamp_s`` (s): wrench (6,) [force (N), torque (N m)] in the encoder's frame."""
        buf, values = self._stamped(stamp_s)
        values[:] = wrench
        return bytes(buf)


class ImuEncoder(_HeaderDoublesEncoder):
    """sensor_msgs/Imu in a fixed frame, without an orientation estimate (orientation_covariance[0] = -1, the
    message's convention): angular velocity (3,) rad/s and linear acceleration (3,) m/s^2 with diagonal
    covariances."""

    def __init__(self, frame_id: str):
        fields = np.zeros(37)  # orientation 4, its covariance 9, angular velocity 3 + 9, linear acceleration 3 + 9
        fields[3], fields[4] = 1.0, -1.0
        super().__init__(frame_id, fields)

    def encode(self, stamp_s: float, angular_velocity, linear_acceleration, gyro_variance: float = 0.0,
               accel_variance: float = 0.0) -> bytes:
        """Imu bytes at ``stamp_s`` (s): rates (3,) rad/s and specific force (3,) m/s^2, the encoder's frame."""
        buf, values = self._stamped(stamp_s)
        values[13:16], values[25:28] = angular_velocity, linear_acceleration
        values[[16, 20, 24]], values[[28, 32, 36]] = gyro_variance, accel_variance
        return bytes(buf)


def decode_imu(data) -> tuple[float, str, np.ndarray, np.ndarray]:
    """(stamp s, frame_id, angular velocity (3,) rad/s, linear acceleration (3,) m/s^2) of Imu bytes."""
    stamp, frame, values = _decode_header_doubles(data, "Imu", 37)
    return stamp, frame, values[13:16], values[25:28]


def decode_wrench_stamped(data) -> tuple[float, str, np.ndarray]:
    """(stamp s, frame_id, wrench (6,) [force N, torque N m]) of WrenchStamped bytes."""
    return _decode_header_doubles(data, "WrenchStamped", 6)


def decode_stamped_doubles(messages, count: int, what: str) -> tuple[np.ndarray, list, np.ndarray, np.ndarray, list]:
    """Decode many raw messages laid out as Header + ``count`` float64 (PoseStamped: 7, WrenchStamped: 6).

    Messages of one size whose bytes up to the doubles equal the first's but for the stamp (a publisher's stream:
    same frame) are decoded together through numpy views of the joined bytes; the others one by one.

    Args:
        messages: the raw messages (bytes).
        count: the float64 fields after the header.
        what: the type's name for error messages.

    Returns:
        (stamps [m] (s), frame_ids [m] (str), values [m, count], kept [m] (indices of the decoded messages, in
        order), errors (InvalidInputError of each message that could not be decoded)).
    """
    by_size: dict[int, list[int]] = {}
    for i, data in enumerate(messages):
        by_size.setdefault(len(data), []).append(i)
    stamps, frames, values, kept, errors = [], [], [], [], []
    for size, group in by_size.items():
        start = None
        try:
            r = CdrReader(messages[group[0]], what)
            r.stamp()
            frame = r.string()
            r.pad(8)
            r.need(8 * count)
            start = r.pos
        except InvalidInputError:
            pass  # decoded one by one below, which reports it
        if start is not None and len(group) > 1:
            n = len(group)
            joined = b"".join([messages[i] for i in group])
            header = np.ndarray((n, start), np.uint8, joined, 0, (size, 1))
            differs = header != header[0]
            differs[:, 4:12] = False  # the stamp may differ
            times = np.ndarray((n,), STAMP_DTYPE, joined, 4, (size,))
            uniform = ~differs.any(axis=1) & (times["nanosec"] < NANOSEC_PER_SEC)
            table = np.ndarray((n, count), F8, joined, start, (size, 8))
            if uniform.all():
                stamps.append(times["sec"] + times["nanosec"] * 1e-9)
                values.append(table.copy())
                frames.extend([frame] * n)
                kept.append(np.asarray(group))
                continue
            stamps.append(times["sec"][uniform] + times["nanosec"][uniform] * 1e-9)
            values.append(table[uniform])
            frames.extend([frame] * int(uniform.sum()))
            kept.append(np.asarray(group)[uniform])
            group = [group[j] for j in np.flatnonzero(~uniform)]
        for i in group:  # the rest one by one
            try:
                r = CdrReader(messages[i], what)
                sec, nanosec = r.stamp()
                frame_i = r.string()
                row = r.fixed_doubles(count)
            except InvalidInputError as exc:
                errors.append(exc)
                continue
            frames.append(frame_i)
            stamps.append(np.array([stamp_seconds(sec, nanosec)]))
            values.append(row[None, :])
            kept.append(np.array([i]))
    if not kept:
        return np.empty(0), [], np.empty((0, count)), np.empty(0, int), errors
    if len(kept) == 1:
        return stamps[0], frames, values[0], kept[0], errors
    indices = np.concatenate(kept)
    order = np.argsort(indices, kind="stable")
    if (order != np.arange(len(order))).any():  # one-by-one rows among the others: back in arrival order
        frames = [frames[j] for j in order]
    return np.concatenate(stamps)[order], frames, np.concatenate(values)[order], indices[order], errors
