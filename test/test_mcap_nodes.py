"""Recorder and replay over real DDS: independent readers, signals, SIGKILL, replay timing."""

from __future__ import annotations

import json
import os
import signal
import time
from collections import Counter

import numpy as np
import pytest

from stewart_vibration.mcap_log import McapRunWriter, QosProfile, RunReader, dump_qos_profiles
from stewart_vibration.processes import start_python_module, wait_for

RECORDER = "stewart_vibration.nodes.mcap_recorder_node"
REPLAY = "stewart_vibration.nodes.mcap_replay_node"
PUBLISHER = "stewart_vibration.nodes.synthetic_run_publisher"
SUITE = ["/legs/joint_states", "/platform/pose", "/legs/force_estimate", "/diagnostics"]


def _env(ros_domain):
    from stewart_vibration.processes import ros_environment

    return ros_environment(ros_domain)


def _tagged_json(proc, tag):
    for line in proc.log_text().splitlines():
        if line.startswith(tag + " "):
            return json.loads(line[len(tag) + 1 :])
    return None


def _start_recorder(tmp_path, env, name="recorder", extra=()):
    args = ["--ros-args", "-p", f"output_dir:={tmp_path / name}", *extra]
    return start_python_module(name, RECORDER, args, env, tmp_path / "logs")


def _mcap(tmp_path, name="recorder"):
    files = sorted((tmp_path / name).glob("*.mcap"))
    assert len(files) == 1, files
    return files[0]


def _run_publisher(tmp_path, env, count, rate, wait=True, topics="joint_states,pose,force,diag"):
    pub = start_python_module(
        "publisher", PUBLISHER, ["--count", str(count), "--rate", str(rate), "--topics", topics], env, tmp_path / "logs"
    )
    if wait:
        assert wait_for(lambda: not pub.alive(), 60), pub.log_text()
        pub.stop()
        sent = _tagged_json(pub, "SYNTHETIC_SENT")
        assert sent, pub.log_text()
        return sent["counts"]
    return pub


def _counts_rosbags(path):
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.EMPTY)  # built only from the definitions stored in the file
    counts = Counter()
    with Reader(path) as reader:
        for c in reader.connections:
            store.register(get_types_from_msg(c.msgdef.data, c.msgtype))
        for c, _t, raw in reader.messages():
            store.deserialize_cdr(raw, c.msgtype)
            counts[c.topic] += 1
    return counts


def _counts_mcap_ros2(path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        return Counter(ch.topic for _s, ch, _m, _d in reader.iter_decoded_messages())


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_recorder_signal_finishes_file_with_every_message(ros_domain, tmp_path, sig):
    env = _env(ros_domain)
    rec = _start_recorder(tmp_path, env)
    try:
        sent = _run_publisher(tmp_path, env, count=150, rate=300)
        time.sleep(0.3)
        os.killpg(rec.popen.pid, sig)
        assert wait_for(lambda: not rec.alive(), 15), rec.log_text()
    finally:
        rec.stop()
    stats = _tagged_json(rec, "MCAP_RECORDER_STATS")
    assert stats and stats["dropped"] == 0, rec.log_text()
    path = _mcap(tmp_path)
    run = RunReader(path)
    assert run.complete and run.profile == "ros2"
    for counts in (_counts_rosbags(path), _counts_mcap_ros2(path)):
        for topic in SUITE:
            assert counts[topic] == sent[topic], (topic, counts, sent)
        assert counts["/rosout"] == stats["per_topic"]["/rosout"]
    topics = {t.topic: t for t in run.topics()}
    js = topics["/legs/joint_states"]
    assert js.type_name == "sensor_msgs/msg/JointState"
    assert "reliability: reliable" in js.offered_qos_profiles
    # publish_time is header.stamp (sim-time origin 1000 s of the synthetic publisher)
    first = next(run.messages(["/legs/joint_states"]))
    assert first.publish_time == 1_000_000_000_000


def test_recorder_sigkill_keeps_completed_chunks(ros_domain, tmp_path):
    env = _env(ros_domain)
    flush_s = 0.2
    rec = _start_recorder(tmp_path, env, extra=["-p", "chunk_size:=4096", "-p", f"flush_period_s:={flush_s}"])
    pub = None
    try:
        pub = _run_publisher(tmp_path, env, count=600, rate=200, wait=False, topics="joint_states")
        assert wait_for(lambda: "subscribed /legs/joint_states" in rec.log_text(), 20)
        time.sleep(1.5)  # mid-run
        os.killpg(rec.popen.pid, signal.SIGKILL)
        assert wait_for(lambda: not rec.alive(), 5)
    finally:
        rec.stop()
        if pub is not None:
            pub.stop()
    run = RunReader(_mcap(tmp_path))
    assert not run.complete
    decoded = list(run.decoded(["/legs/joint_states"]))
    n = len(decoded)
    assert n > 0 and all(len(msg.name) == 12 for _raw, msg in decoded)
    # Samples are sent at 200 Hz from header stamp 1000 s; everything older than the
    # flush period (plus scheduling slack) before the kill must be on disk.
    last = decoded[-1][0].publish_time
    assert [raw.publish_time for raw, _m in decoded] == sorted(raw.publish_time for raw, _m in decoded)
    assert n >= 10 and last > 1_000_000_000_000


def _write_source_run(path, n=300, seed=1):
    """A run with irregular spacing (4..16 ms) on two topics, serialized by rclpy itself."""
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState

    rng = np.random.default_rng(seed)
    t = 10**18 + np.cumsum(rng.uniform(4e6, 16e6, n)).astype(np.int64)
    w = McapRunWriter(path)
    qos = dump_qos_profiles([QosProfile(history="unknown", depth=0)])
    w.add_topic("/legs/joint_states", "sensor_msgs/msg/JointState", qos)
    for i, ti in enumerate(t):
        msg = JointState(name=["leg_1"], position=[float(i)])
        w.submit("/legs/joint_states", int(ti), serialize_message(msg))
    w.close()
    return t


def _replay_into_recorder(tmp_path, env, src, rate, name):
    rec = _start_recorder(tmp_path, env, name=name, extra=["-p", "topics:=[/legs/joint_states]"])
    try:
        rep = start_python_module(
            f"replay_{name}",
            REPLAY,
            ["--ros-args", "-p", f"path:={src}", "-p", f"rate:={rate}", "-p", "wait_for_subscribers_s:=20.0"],
            env,
            tmp_path / "logs",
        )
        try:
            assert wait_for(lambda: not rep.alive(), 60), rep.log_text()
        finally:
            rep.stop()
        time.sleep(0.3)
    finally:
        rec.stop()
    done = _tagged_json(rep, "MCAP_REPLAY_DONE")
    assert done and done["published"]["/legs/joint_states"] > 0, rep.log_text()
    run = RunReader(_mcap(tmp_path, name))
    msgs = list(run.messages(["/legs/joint_states"]))
    return done, np.array([m.log_time for m in msgs]), [m.data for m in msgs]


def test_replay_timing_bytes_and_rate(ros_domain, tmp_path):
    env = _env(ros_domain)
    src = tmp_path / "source.mcap"
    t = _write_source_run(src)
    src_bytes = [m.data for m in RunReader(src).messages()]

    done, t1, data1 = _replay_into_recorder(tmp_path, env, src, 1.0, "rec_rate1")
    assert data1 == src_bytes  # the recorded bytes, republished as they are
    err = np.abs(np.diff(t1) - np.diff(t)) / 1e6
    print(f"rate 1: interval error ms median {np.median(err):.3f} p99 {np.percentile(err, 99):.3f} "
          f"max {err.max():.3f}; "
          f"replay lateness max {done['lateness_max_s'] * 1e3:.3f} ms; worst {done['lateness_worst']}")
    # The replayer's own schedule: 99% of messages leave within 1 ms of their due time (so
    # their intervals are within 1 ms of the recorded ones). The rare worst case is the OS
    # preempting the pacing thread: a bare sleep+spin loop without ROS shows up to ~3 ms
    # on this 2-core VM, so the max only gets a sanity bound.
    assert done["lateness_p99_s"] < 1e-3 and done["lateness_max_s"] < 10e-3
    # As received over DDS by another process on this 2-core machine: the bulk is well
    # inside 1 ms; the far tail carries the receiver's scheduling jitter, not the replay's.
    assert np.percentile(err, 95) < 1.0 and np.median(err) < 0.3

    done10, t10, data10 = _replay_into_recorder(tmp_path, env, src, 10.0, "rec_rate10")
    assert len(data10) == len(src_bytes)
    speedup = (t[-1] - t[0]) / (t10[-1] - t10[0])
    print(f"rate 10: speed-up {speedup:.2f}")
    assert 9.0 < speedup < 11.0
