"""The numpy CDR codec of the high-rate topics against rclpy's own serializer: rclpy reads what
we write, we read what rclpy writes (uniform and mixed trajectories, batches), malformed bytes give a typed
error."""

from __future__ import annotations

import numpy as np
import pytest
from builtin_interfaces.msg import Duration
from geometry_msgs.msg import PoseStamped, WrenchStamped
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from stewart_vibration.errors import InvalidInputError
from stewart_vibration.messages import cdr
from stewart_vibration.messages.joint_states import (
    JointStateDecoder,
    JointStateEncoder,
    decode_joint_states,
    decode_joint_states_dropping_malformed,
)
from stewart_vibration.messages.joint_trajectory import decode_joint_trajectory, encode_joint_trajectory
from stewart_vibration.messages.stamped_doubles import PoseStampedEncoder, WrenchStampedEncoder, decode_pose_stamped

NAMES = [f"leg_{i}" for i in range(1, 7)] + [f"vib_{i}" for i in range(1, 7)]
RNG = np.random.default_rng(3)


def stamp_of(header):
    return header.stamp.sec + header.stamp.nanosec * 1e-9


def test_joint_state_round_trips_through_rclpy():
    p, v, e = RNG.normal(size=(3, 12))
    msg = deserialize_message(JointStateEncoder(NAMES).encode(12.345678901, p, v, e), JointState)
    assert list(msg.name) == NAMES and (msg.header.stamp.sec, msg.header.stamp.nanosec) == (12, 345678901)
    assert np.array_equal(msg.position, p) and np.array_equal(msg.velocity, v) and np.array_equal(msg.effort, e)
    only = deserialize_message(JointStateEncoder(NAMES[:6], "base", fields=("effort",)).encode(1.5, effort=e[:6]),
                               JointState)
    assert len(only.position) == 0 and np.array_equal(only.effort, e[:6]) and only.header.frame_id == "base"
    theirs = JointState(name=NAMES, position=p.tolist(), effort=e.tolist())
    theirs.header.stamp.sec, theirs.header.stamp.nanosec = 3, 7
    decoded = JointStateDecoder().decode(serialize_message(theirs))
    assert decoded.names == tuple(NAMES) and decoded.stamp == pytest.approx(3 + 7e-9)
    assert np.array_equal(decoded.position, p) and decoded.velocity.size == 0 and np.array_equal(decoded.effort, e)


def test_joint_state_batches_match_one_by_one_and_split_on_layout_changes():
    enc = JointStateEncoder(NAMES)
    ours = [enc.encode(1 + 0.002 * i, *RNG.normal(size=(3, 12))) for i in range(20)]
    other = serialize_message(JointState(name=["a", "b"], position=[1.0, 2.0]))
    batches = decode_joint_states(ours[:7] + [other] + ours[7:])
    assert [len(b.stamps) for b in batches] == [7, 1, 13] and batches[1].names == ("a", "b")
    assert np.isnan(batches[1].velocity).all()
    single = [deserialize_message(m, JointState) for m in ours]
    joined = np.concatenate([batches[0].position, batches[2].position])
    assert np.array_equal(joined, np.array([m.position for m in single]))
    assert np.array_equal(np.concatenate([batches[0].stamps, batches[2].stamps]),
                          np.array([stamp_of(m.header) for m in single]))



def test_malformed_joint_states_are_dropped_alone_with_their_arrivals():
    enc = JointStateEncoder(NAMES)
    good = [enc.encode(1 + 0.002 * i, *RNG.normal(size=(3, 12))) for i in range(10)]
    truncated, garbage = good[0][:30], b"\x00\x01\x00\x00" + bytes(7)
    messages = good[:3] + [truncated] + good[3:8] + [garbage] + good[8:]
    arrivals = np.arange(len(messages)) * 10.0  # one distinct arrival time per message
    reasons: list[str] = []
    batches, kept = decode_joint_states_dropping_malformed(messages, on_malformed=reasons.append)
    assert len(reasons) == 2 and all("truncated" in r or "JointState" in r for r in reasons), reasons
    assert kept.tolist() == [0, 1, 2, 4, 5, 6, 7, 8, 10, 11]
    rows = np.concatenate([b.position for b in batches])
    single = [deserialize_message(m, JointState) for m in good]  # rclpy's reading, message by message
    assert np.array_equal(rows, np.array([m.position for m in single]))
    assert np.array_equal(np.concatenate([b.stamps for b in batches]), [stamp_of(m.header) for m in single])
    assert np.array_equal(arrivals[kept], [0, 10, 20, 40, 50, 60, 70, 80, 100, 110])
    clean, all_kept = decode_joint_states_dropping_malformed(good)
    assert all_kept.tolist() == list(range(10)) and sum(len(b.stamps) for b in clean) == 10

def test_pose_wrench_clock_round_trip():
    msg = deserialize_message(PoseStampedEncoder("base").encode(3.25, [1, 2, 3], [0.1, 0.2, 0.3, 0.9]),
                              PoseStamped)
    assert msg.header.frame_id == "base" and stamp_of(msg.header) == 3.25
    assert (msg.pose.position.x, msg.pose.position.y, msg.pose.position.z) == (1, 2, 3)
    assert (msg.pose.orientation.x, msg.pose.orientation.w) == (0.1, 0.9)
    stamp, frame, position, quat = decode_pose_stamped(serialize_message(msg))
    assert (stamp, frame) == (3.25, "base") and np.array_equal(position, [1, 2, 3])
    w = deserialize_message(WrenchStampedEncoder("base").encode(2.0, np.arange(6.0)), WrenchStamped)
    assert (w.wrench.force.y, w.wrench.torque.z) == (1.0, 5.0)
    c = deserialize_message(cdr.encode_clock(7.000000009), Clock)
    assert (c.clock.sec, c.clock.nanosec) == (7, 9)


@pytest.mark.parametrize("joints,points,vel,acc,frame", [
    (6, 1700, True, True, ""), (6, 3, False, False, "ab"), (6, 51, True, False, "abcd"), (5, 7, True, True, ""),
    (1, 4, True, False, "x"), (6, 1, False, False, ""), (3, 5, False, False, "base"), (2, 6, True, True, "abc"),
])
def test_trajectories_round_trip(joints, points, vel, acc, frame):
    names = [f"j{i}" for i in range(joints)]
    times = np.arange(1, points + 1) * 0.001
    pos = RNG.normal(size=(points, joints))
    velocities = RNG.normal(size=(points, joints)) if vel else None
    accelerations = RNG.normal(size=(points, joints)) if acc else None
    msg = deserialize_message(encode_joint_trajectory(names, 10.5, times, pos, velocities, accelerations, frame),
                              JointTrajectory)
    assert list(msg.joint_names) == names and msg.header.frame_id == frame and len(msg.points) == points
    for i, point in enumerate(msg.points):
        assert np.array_equal(point.positions, pos[i])
        assert np.array_equal(point.velocities, velocities[i]) if vel else len(point.velocities) == 0
        assert np.array_equal(point.accelerations, accelerations[i]) if acc else len(point.accelerations) == 0
        assert point.time_from_start.sec + point.time_from_start.nanosec * 1e-9 == pytest.approx(times[i], abs=1e-12)
    back = decode_joint_trajectory(serialize_message(msg))
    assert back.names == tuple(names) and back.stamp == 10.5 and np.allclose(back.times, times, atol=1e-12)
    assert np.array_equal(back.positions, pos)
    assert (back.velocities is None) if not vel else np.array_equal(back.velocities, velocities)


def test_mixed_trajectory_points_decode_one_by_one_or_are_refused():
    msg = JointTrajectory(joint_names=["a", "b"])
    msg.points = [JointTrajectoryPoint(positions=[1.0, 2.0], time_from_start=Duration(sec=1)),
                  JointTrajectoryPoint(positions=[3.0, 4.0], velocities=[0.0, 0.5], time_from_start=Duration(sec=2))]
    with pytest.raises(InvalidInputError, match="differ in their number of velocities"):
        decode_joint_trajectory(serialize_message(msg))
    msg.points[0].velocities = [0.1, 0.2]
    back = decode_joint_trajectory(serialize_message(msg))
    assert np.array_equal(back.velocities, [[0.1, 0.2], [0.0, 0.5]]) and np.array_equal(back.times, [1.0, 2.0])


def test_malformed_bytes_give_a_typed_error():
    good = encode_joint_trajectory(NAMES[:6], 1.0, [0.1, 0.2], np.zeros((2, 6)), np.zeros((2, 6)))
    state = JointStateEncoder(NAMES).encode(1.0, *np.zeros((3, 12)))
    junk = [b"", b"\x00\x01\x00\x00", bytes(RNG.integers(0, 256, 300, dtype=np.uint8)), good[:40], good[:-3],
            state[:50], b"\x01\x00\x00\x00" + good[4:]]
    for data in junk:
        for decode in (decode_joint_trajectory, JointStateDecoder().decode, decode_pose_stamped):
            try:
                decode(data)
            except InvalidInputError as exc:
                assert str(exc)
