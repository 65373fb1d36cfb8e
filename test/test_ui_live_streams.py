"""The planning page's 500 Hz streams (ui/live_streams.py) from real CDR bytes: the rows the buffers and the
plots get (decimated across batches), the latest values, malformed messages counted per topic and the rest
kept, the pose estimate's freshness, and when the subscriptions are held (stepped time)."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.errors import StewartError
from stewart_vibration.messages.joint_states import JointStateEncoder
from stewart_vibration.messages.stamped_doubles import PoseStampedEncoder
from stewart_vibration.nodes.message_conversions import JointColumns
from stewart_vibration.robot import LEG_NAMES, VIB_NAMES
from stewart_vibration.ui.live_streams import (
    DROP,
    FORCES,
    JOINTS,
    POSES,
    SUBSCRIBE,
    LiveStreams,
    StreamWatch,
)

# vib_* first: the columns are found by name, not by place
JOINT_ENCODER = JointStateEncoder([*VIB_NAMES, *LEG_NAMES])
FORCE_ENCODER = JointStateEncoder(LEG_NAMES, fields=("effort",))
POSE_ENCODER = PoseStampedEncoder("base")


def streams(plot_rate_hz=250.0):
    refused = []
    live = LiveStreams(10.0, plot_rate_hz, JointColumns(), lambda topic, error, count=1:
                       refused.append((topic, error.reason, count)))
    return live, refused


def joint_state(k: int) -> bytes:
    """Sample k at 2 ms: vib_i = k + i um, leg_i = 0.3 m + k um; efforts: leg_i 40 + i N, vib_i 0."""
    vib = (k + np.arange(1, 7)) * 1e-6
    legs = 0.3 + np.full(6, k * 1e-6)
    return JOINT_ENCODER.encode(0.002 * k, position=np.r_[vib, legs], velocity=np.zeros(12),
                                effort=np.r_[np.zeros(6), 40.0 + np.arange(1, 7)])


def test_joint_states_fill_the_buffer_the_plots_and_the_latest_legs():
    live, refused = streams()  # 500 Hz shown at 250 Hz: every other sample
    for k in range(3):
        live.receive(JOINTS, joint_state(k))
    live.drain(now=5.0)
    for k in range(3, 7):
        live.receive(JOINTS, joint_state(k))
    live.drain(now=5.1)
    t, rows = live.buffers.joints.arrays(24)
    np.testing.assert_allclose(t, 0.002 * np.arange(7))
    # legs then vib, positions then efforts (the run summary's layout)
    np.testing.assert_allclose(rows[4], np.r_[np.full(6, 0.300004), (4 + np.arange(1, 7)) * 1e-6,
                                              40.0 + np.arange(1, 7), np.zeros(6)])
    plots = live.take_plots()
    assert [row[0] for row in plots["joints"]] == pytest.approx([0.0, 0.004, 0.008, 0.012])  # across batches
    assert plots["joints"][1] == pytest.approx([0.004, 3, 4, 5, 6, 7, 8, 41, 42, 43, 44, 45, 46])  # t, um, N
    assert live.take_plots() == {"joints": [], "forces": []}
    stamp, row = live.latest_joints
    assert stamp == pytest.approx(0.012) and row[6] == pytest.approx(7e-6)
    assert live.seen == {JOINTS: 5.1} and refused == []


def test_a_joint_state_without_its_names_is_counted_and_the_others_kept():
    live, refused = streams()
    no_vib = JointStateEncoder(LEG_NAMES).encode(0.0, np.zeros(6), np.zeros(6), np.zeros(6))
    live.receive(JOINTS, no_vib)
    live.receive(JOINTS, no_vib)
    live.receive(JOINTS, b"\x00\x01\x00\x00 not a joint state")
    live.receive(JOINTS, joint_state(1))
    live.drain(now=1.0)
    # the bytes that are no JointState first (found while decoding), then the batch that lacks the vib_* names
    assert [(topic, count) for topic, _, count in refused] == [(JOINTS, 1), (JOINTS, 2)]
    assert refused[1][1] == "names name"
    t, _ = live.buffers.joints.arrays(24)
    np.testing.assert_allclose(t, [0.002])


def test_forces_are_decimated_across_batches_in_their_own_phase():
    live, refused = streams()
    for batch in ((0, 1, 2), (3, 4, 5)):
        for k in batch:
            live.receive(FORCES, FORCE_ENCODER.encode(0.002 * k, effort=np.full(6, float(k))))
        live.drain(now=2.0)
    plots = live.take_plots()["forces"]
    assert [row[0] for row in plots] == pytest.approx([0.0, 0.004, 0.008])
    assert plots[2][1:] == [4.0] * 6 and live.latest_joints is None and refused == []
    t, rows = live.buffers.forces.arrays(6)
    assert len(t) == 6 and rows[5].tolist() == [5.0] * 6


def test_pose_estimates_are_returned_for_the_move_and_their_freshness_kept():
    live, refused = streams()
    with pytest.raises(StewartError, match="no recent platform/pose_estimate"):
        live.estimate(0.0)
    level = [0.0, 0.0, 0.0, 1.0]
    live.receive(POSES, POSE_ENCODER.encode(1.0, [0.001, 0.0, 0.16], level))
    live.receive(POSES, POSE_ENCODER.encode(1.002, [0.0, 0.0, 0.16], [0.0, 0.0, 0.0, 2.0]))  # not a unit quaternion
    live.receive(POSES, POSE_ENCODER.encode(1.004, [0.002, 0.0, 0.16], level))
    stamps, poses = live.drain(now=10.0)
    np.testing.assert_allclose(stamps, [1.0, 1.004])
    np.testing.assert_allclose(poses[:, 0], [0.001, 0.002])
    assert [topic for topic, _, _ in refused] == [POSES]
    np.testing.assert_allclose(live.estimate(11.0), [0.002, 0.0, 0.16, 0.0, 0.0, 0.0], atol=1e-12)
    with pytest.raises(StewartError):
        live.estimate(11.01)  # over a second since the last one came
    stamps, poses = live.drain(now=12.0)  # nothing new
    assert stamps.shape == (0,) and poses.shape == (0, 6) and live.seen[POSES] == 10.0


def test_the_streams_are_held_while_watched_and_dropped_five_seconds_after():
    watch = StreamWatch(unwatched_since=0.0)
    assert watch.step(1.0, watched=False, subscribed=False) is None  # nobody ever watched: nothing to hold
    assert watch.step(2.0, watched=True, subscribed=False) == SUBSCRIBE
    assert watch.step(3.0, watched=True, subscribed=True) is None
    assert watch.step(7.9, watched=False, subscribed=True) is None  # 4.9 s since the last watcher
    assert watch.step(8.01, watched=False, subscribed=True) == DROP
    assert watch.step(9.0, watched=False, subscribed=False) is None
    assert watch.step(9.5, watched=True, subscribed=False) == SUBSCRIBE
