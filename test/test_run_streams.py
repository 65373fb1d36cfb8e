"""A run's streams decoded in one pass (analysis.run_streams through run_signals.load_signals), checked against
the values the messages were made from (serialized by rosbags, an independent CDR implementation): columns by
name whatever the message's order, rows in log-time order file after file whatever the order in the file,
batch boundaries invisible, and a message that cannot be decoded left out and counted, never a crash."""

from __future__ import annotations

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from stewart_vibration.analysis import run_streams
from stewart_vibration.analysis.run_signals import load_signals
from stewart_vibration.kinematics.rotations import quaternion_from_rpy
from stewart_vibration.mcap_log import McapRunWriter
from stewart_vibration.mcap_log.reader import open_run
from stewart_vibration.robot import LEG_NAMES, VIB_NAMES

STORE = get_typestore(Stores.ROS2_JAZZY)
T = STORE.types
NAMES = LEG_NAMES + VIB_NAMES
RNG = np.random.default_rng(7)


def header(t_s):
    ns = round(t_s * 1e9)
    return T["std_msgs/msg/Header"](T["builtin_interfaces/msg/Time"](ns // 10**9, ns % 10**9), "base")


def cdr(msg, type_name):
    return bytes(STORE.serialize_cdr(msg, type_name))


def joint_state(t_s, values, names=NAMES):
    """values [3, 12] (position, velocity, effort) in NAMES order, sent in ``names`` order."""
    order = [NAMES.index(n) for n in names]
    return cdr(T["sensor_msgs/msg/JointState"](header(t_s), list(names), *(np.array(v)[order] for v in values)),
               "sensor_msgs/msg/JointState")


def pose_stamped(t_s, pose):
    q = quaternion_from_rpy(pose[3:])
    p = T["geometry_msgs/msg/Pose"](T["geometry_msgs/msg/Point"](*pose[:3]), T["geometry_msgs/msg/Quaternion"](*q))
    return cdr(T["geometry_msgs/msg/PoseStamped"](header(t_s), p), "geometry_msgs/msg/PoseStamped")


def wrench_stamped(t_s, w):
    v3 = T["geometry_msgs/msg/Vector3"]
    return cdr(T["geometry_msgs/msg/WrenchStamped"](header(t_s), T["geometry_msgs/msg/Wrench"](v3(*w[:3]), v3(*w[3:]))),
               "geometry_msgs/msg/WrenchStamped")


def clock(t_s):
    ns = round(t_s * 1e9)
    return cdr(T["rosgraph_msgs/msg/Clock"](T["builtin_interfaces/msg/Time"](ns // 10**9, ns % 10**9)),
               "rosgraph_msgs/msg/Clock")


TOPICS = {"/r/legs/joint_states": "sensor_msgs/msg/JointState",
          "/r/ground_truth/platform_pose": "geometry_msgs/msg/PoseStamped",
          "/r/ground_truth/tissue_wrench": "geometry_msgs/msg/WrenchStamped", "/clock": "rosgraph_msgs/msg/Clock"}


def write_run(path, start_s, n, shuffle=False, extra=()):
    """A file of n samples every 2 ms from start_s on every TOPICS topic (written in a shuffled order when
    ``shuffle``, with each message's log time its stamp), plus ``extra`` (topic, log_time_ns, bytes); returns
    the values made, in time order."""
    t = start_s + 0.002 * np.arange(n)
    states = RNG.normal(size=(n, 3, 12))
    poses = np.column_stack([RNG.normal(scale=0.01, size=(n, 3)), RNG.uniform(-0.3, 0.3, size=(n, 3))])
    wrenches = RNG.normal(size=(n, 6))
    rows = []
    for i in range(n):
        names = NAMES if i % 3 else list(reversed(NAMES))  # columns come by name, whatever their order
        log = round(t[i] * 1e9)
        rows += [("/r/legs/joint_states", log, joint_state(t[i], states[i], names)),
                 ("/r/ground_truth/platform_pose", log, pose_stamped(t[i], poses[i])),
                 ("/r/ground_truth/tissue_wrench", log, wrench_stamped(t[i], wrenches[i])),
                 ("/clock", log, clock(t[i]))]
    rows += list(extra)
    if shuffle:
        rows = [rows[i] for i in RNG.permutation(len(rows))]
    w = McapRunWriter(path)
    for topic, type_name in TOPICS.items():
        w.add_topic(topic, type_name, "[]")
    for topic, log, data in rows:
        w.submit(topic, log, data)
    w.close()
    return t, states, poses, wrenches


def check(signals, t, states, poses, wrenches):
    jt, joints = signals["sensed_joints"]
    np.testing.assert_allclose(jt, t, atol=1e-9)
    for k, field in enumerate(("position", "velocity", "effort")):
        np.testing.assert_array_equal(joints[field], states[:, k])
    pt, pose = signals["pose"]
    np.testing.assert_allclose(pt, t, atol=1e-9)
    np.testing.assert_allclose(pose, poses, atol=1e-12)
    wt, wrench = signals["tissue_wrench"]
    np.testing.assert_allclose(wt, t, atol=1e-9)
    np.testing.assert_array_equal(wrench, wrenches)
    np.testing.assert_allclose(signals["clock"], t, atol=1e-9)


@pytest.mark.parametrize("shuffle", [False, True])
@pytest.mark.parametrize("batch", [run_streams.BATCH_MESSAGES, 7])
def test_streams_come_back_as_made_in_log_time_order(tmp_path, monkeypatch, shuffle, batch):
    monkeypatch.setattr(run_streams, "BATCH_MESSAGES", batch)
    made = write_run(tmp_path / "run.mcap", 10.0, 60, shuffle=shuffle)
    signals = load_signals(tmp_path / "run.mcap")
    check(signals, *made)
    assert signals["undecodable"] == {}
    np.testing.assert_array_equal(signals["stream_stamps"]["legs/joint_states"], np.round(made[0] * 1e9))


def test_the_files_of_a_run_folder_are_read_file_after_file(tmp_path):
    folder = tmp_path / "run"
    folder.mkdir()
    first = write_run(folder / "run_b.mcap", 10.0, 30)
    second = write_run(folder / "run_a.mcap", 20.0, 30)  # its name sorts first: the order is the files' times
    signals = load_signals(folder)
    check(signals, *(np.concatenate([a, b]) for a, b in zip(first, second, strict=True)))
    assert [(f["file"], f["states"]) for f in signals["files"]] == [("run_b.mcap", 30), ("run_a.mcap", 30)]
    assert signals["files"][1]["first_s"] == pytest.approx(20.0)


def test_a_message_that_cannot_be_decoded_is_left_out_and_counted(tmp_path, monkeypatch):
    monkeypatch.setattr(run_streams, "BATCH_MESSAGES", 16)
    good = joint_state(10.1, np.zeros((3, 12)))
    extra = [("/r/legs/joint_states", 10_100_000_000, good[:40]),  # cut inside its names
             ("/r/legs/joint_states", 10_101_000_000, joint_state(10.101, np.zeros((3, 12)))[:-8]),  # short
             ("/r/legs/joint_states", 10_102_000_000, joint_state(10.102, np.zeros((3, 6)), names=LEG_NAMES)),
             ("/r/ground_truth/platform_pose", 10_100_000_000, pose_stamped(10.1, np.zeros(6))[:30]),
             ("/clock", 10_100_000_000, b"\x00\x01")]
    made = write_run(tmp_path / "run.mcap", 10.0, 40, extra=extra)
    signals = load_signals(tmp_path / "run.mcap")
    check(signals, *made)  # the states without the vib_* columns are not rows either
    assert signals["undecodable"] == {"legs/joint_states": 2, "ground_truth/platform_pose": 1, "/clock": 1}


def test_a_pose_that_is_not_one_is_kept_as_nan_for_the_limit_check(tmp_path):
    bad = bytearray(pose_stamped(10.05, np.zeros(6)))
    bad[-32:] = bytes(32)  # a zero quaternion
    made = write_run(tmp_path / "run.mcap", 10.0, 20, extra=[("/r/ground_truth/platform_pose", 10_050_000_000,
                                                                bytes(bad))])
    pt, pose = load_signals(tmp_path / "run.mcap")["pose"]
    row = int(np.flatnonzero(np.isclose(pt, 10.05))[-1])
    assert np.isnan(pose[row]).all() and np.isfinite(np.delete(pose, row, axis=0)).all()
    assert pt.size == made[0].size + 1


def test_a_file_of_many_chunks_is_read_chunk_after_chunk_as_its_log_time_order(tmp_path):
    made = write_run(tmp_path / "run.mcap", 10.0, 1500)
    reader = open_run(tmp_path / "run.mcap")
    assert len(reader._chunk_indexes) > 3  # the recorder's 256 KiB chunks
    ordered = [(m.topic, m.log_time, m.data) for m in reader.messages(log_time_order=True)]
    in_file = [(m.topic, m.log_time, m.data) for m in reader.messages(log_time_order=False)]
    assert sorted(in_file) == sorted(ordered)
    for topic in TOPICS:  # each topic in the same order either way
        assert [m for m in in_file if m[0] == topic] == [m for m in ordered if m[0] == topic]
    check(load_signals(reader), *made)


def test_rows_beyond_the_expected_count_are_kept_in_order():
    rows = run_streams._Rows(2, (6,))  # a file whose statistics undercount: the arrays grow
    values = np.arange(30.0).reshape(5, 6)
    rows.append(np.array([1, 3]), 0, np.array([0.1, 0.3]), values[:2])
    rows.append(np.array([2, 4, 5]), 0, np.array([0.2, 0.4, 0.5]), values[2:])
    times, got = rows.in_order()
    np.testing.assert_array_equal(times, [0.1, 0.2, 0.3, 0.4, 0.5])
    np.testing.assert_array_equal(got, values[[0, 2, 1, 3, 4]])


def test_a_few_topics_of_a_long_file_come_in_the_libraries_log_time_order(tmp_path):
    from mcap.reader import make_reader

    write_run(tmp_path / "run.mcap", 10.0, 1500, shuffle=True)  # many chunks, each topic out of order in them
    reader = open_run(tmp_path / "run.mcap")
    for topics in (["/clock"], ["/clock", "/r/ground_truth/tissue_wrench"]):
        ours = [(m.topic, m.log_time, m.data) for m in reader.messages(topics)]
        with open(tmp_path / "run.mcap", "rb") as f:
            theirs = [(c.topic, m.log_time, m.data) for _s, c, m in make_reader(f).iter_messages(topics=topics,
                                                                                                  log_time_order=True)]
        assert len(ours) == len(theirs) > 1000 and ours == theirs


@pytest.mark.parametrize("batch", [run_streams.BATCH_MESSAGES, 7, 97])
def test_a_run_read_in_windows_keeps_their_rows_and_checks_every_state(tmp_path, monkeypatch, robot, batch):
    """With windows and a robot, the 500 Hz streams keep only the rows inside the windows, the limit figures are
    those of every state (check_limits over the whole run's arrays, read without windows), and everything else
    (stamps, /clock, the wrenches of a run with tissue) is as without windows; batches cut the states anywhere."""
    from stewart_vibration.analysis.limit_check import check_limits

    monkeypatch.setattr(run_streams, "BATCH_MESSAGES", batch)
    write_run(tmp_path / "run.mcap", 10.0, 600)
    whole = load_signals(tmp_path / "run.mcap")
    windows = [(10.2, 10.5), (10.9, 11.0)]
    part = load_signals(tmp_path / "run.mcap", windows=windows, robot=robot)
    assert part["limit_figures"] == check_limits(robot, whole["joints"], whole["pose"], whole["clock"])
    for key in ("joints", "sensed_joints", "pose"):
        t, values = whole[key]
        inside = ((t >= 10.2) & (t <= 10.5)) | ((t >= 10.9) & (t <= 11.0))
        assert 0 < inside.sum() < t.size
        np.testing.assert_array_equal(part[key][0], t[inside])
        rows = {k: v[inside] for k, v in values.items()} if isinstance(values, dict) else {"": values[inside]}
        got = part[key][1] if isinstance(values, dict) else {"": part[key][1]}
        for k, v in rows.items():
            np.testing.assert_array_equal(got[k], v)
    np.testing.assert_array_equal(part["tissue_wrench"][1], whole["tissue_wrench"][1])  # a tissue run: whole
    np.testing.assert_array_equal(part["clock"], whole["clock"])
    for key, stamps in whole["stream_stamps"].items():
        np.testing.assert_array_equal(part["stream_stamps"][key], stamps)
    assert part["files"] == whole["files"] and part["stream_counts"] == whole["stream_counts"]
