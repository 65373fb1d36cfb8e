"""``stewart-vibration mcap-recover``: a file cut by a crash is rebuilt complete and indexed.

What was flushed is counted independently of the code under test: the mcap
library's StreamReader walks the raw file and every Chunk record it reads whole
counts (mcap's breakup_chunk). The rebuilt file is read back by rosbags (as a
bag directory) and by the mcap reader through its summary and indexes.
"""

from __future__ import annotations

import functools
import json
import os
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import pytest
from mcap.reader import make_reader
from mcap.stream_reader import StreamReader, breakup_chunk

from stewart_vibration.mcap_log import McapRunWriter, QosProfile, dump_qos_profiles
from stewart_vibration.runtime.processes import ros_environment, start_python_module, wait_for

RECORDER = "stewart_vibration.nodes.mcap_recorder_node"
JS = "/legs/joint_states"
POSE = "/ground_truth/platform_pose"


def run_cli(*args, timeout=120):
    return subprocess.run([sys.executable, "-m", "stewart_vibration", *args], capture_output=True, text=True,
                          timeout=timeout)


def flushed_messages(path: Path) -> list:
    """(topic, log_time, data) of every message in a Chunk record that is whole in the raw file."""
    out, channels = [], {}
    with open(path, "rb") as f:
        try:
            for record in StreamReader(f, emit_chunks=True).records:
                if type(record).__name__ != "Chunk":
                    continue
                for inner in breakup_chunk(record, validate_crc=True):
                    kind = type(inner).__name__
                    if kind == "Channel":
                        channels[inner.id] = inner.topic
                    elif kind == "Message":
                        out.append((channels[inner.channel_id], inner.log_time, bytes(inner.data)))
        except Exception:  # noqa: BLE001 - the cut tail
            pass
    return out


def rosbags_messages(folder: Path) -> list:
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.EMPTY)  # types only from the definitions stored in the file
    out = []
    with Reader(folder) as reader:
        for c in reader.connections:
            store.register(get_types_from_msg(c.msgdef.data, c.msgtype))
        for c, t, raw in reader.messages():
            store.deserialize_cdr(raw, c.msgtype)
            out.append((c.topic, t, bytes(raw)))
    return out


def indexed_mcap_messages(path: Path) -> tuple[list, object]:
    """Messages through the summary/indexes (seeking reader) and the summary itself."""
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert reader.get_header().profile == "ros2"
        msgs = [(ch.topic, m.log_time, bytes(m.data)) for _s, ch, m in reader.iter_messages(log_time_order=True)]
    return msgs, summary


def check_rosbag2_layout(path: Path, expected_count: int) -> None:
    msgs, summary = indexed_mcap_messages(path)
    assert summary is not None and summary.statistics.message_count == expected_count == len(msgs)
    assert summary.chunk_indexes and all(ci.compression == "zstd" for ci in summary.chunk_indexes)
    assert all(ci.message_index_offsets for ci in summary.chunk_indexes)  # message indexes written
    assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
    for ch in summary.channels.values():
        assert ch.message_encoding == "cdr"
        assert "offered_qos_profiles" in ch.metadata and "topic_type_hash" in ch.metadata
    with open(path, "rb") as f:
        meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    assert "serialized_metadata" in meta["rosbag2"]


@functools.cache
def _store():
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


def _cdr(type_name: str, i: int) -> bytes:
    """A JointState or PoseStamped with header.stamp = 1000 s + i ns, serialized by rosbags."""
    store = _store()
    t = store.types
    header = t["std_msgs/msg/Header"](t["builtin_interfaces/msg/Time"](1000, i), "base")
    if type_name.endswith("JointState"):
        import numpy as np

        msg = t[type_name](header, [f"leg_{k}" for k in range(1, 7)], np.full(6, float(i)), np.zeros(0),
                           np.zeros(0))
    else:
        pose = t["geometry_msgs/msg/Pose"](t["geometry_msgs/msg/Point"](0.0, 0.0, 0.16 + i * 1e-9),
                                           t["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0))
        msg = t[type_name](header, pose)
    return bytes(store.serialize_cdr(msg, type_name))


@pytest.fixture
def written_run(tmp_path):
    """A complete 2-topic run in small chunks (so a cut leaves many whole chunks)."""
    path = tmp_path / "src" / "run.mcap"
    w = McapRunWriter(path, chunk_size=8 * 1024, flush_period_s=60.0)
    qos = dump_qos_profiles([QosProfile(depth=500)])
    w.add_topic(JS, "sensor_msgs/msg/JointState", qos, "RIHS01_" + "ab" * 32)
    w.add_topic(POSE, "geometry_msgs/msg/PoseStamped", qos)
    for i in range(3000):
        w.submit(JS, 10**9 + i * 10**6, _cdr("sensor_msgs/msg/JointState", i))
        if i % 2 == 0:
            w.submit(POSE, 10**9 + i * 10**6 + 1, _cdr("geometry_msgs/msg/PoseStamped", i))
    w.close()
    return path


@pytest.mark.parametrize("fraction", [0.25, 0.5, 0.83, 0.999])
def test_cut_file_rebuilt_with_every_flushed_message(written_run, tmp_path, fraction):
    data = written_run.read_bytes()
    folder = tmp_path / "crashed"
    folder.mkdir()
    cut = folder / "run.mcap"
    cut.write_bytes(data[: int(len(data) * fraction)])
    flushed = flushed_messages(cut)
    assert 0 < len(flushed) <= 4500

    out = run_cli("mcap-recover", str(cut))
    assert out.returncode == 1, out.stdout + out.stderr  # rebuilt, but the input was cut
    assert "Traceback" not in out.stderr
    assert f"recovered: {len(flushed):,} messages" in out.stdout and "lost:" in out.stdout
    assert f"of {len(data[: int(len(data) * fraction)]):,}" in out.stdout  # how much of the file was read
    rebuilt = folder / "run.recovered.mcap"
    check_rosbag2_layout(rebuilt, len(flushed))
    assert sorted(indexed_mcap_messages(rebuilt)[0]) == sorted(flushed)
    assert sorted(rosbags_messages(folder)) == sorted(flushed)  # the folder is a bag directory now


def test_complete_file_rebuilt_nothing_lost_json(written_run, tmp_path):
    out_dir = tmp_path / "copy"
    out = run_cli("mcap-recover", str(written_run), str(out_dir) + "/", "--json")
    assert out.returncode == 0, out.stdout + out.stderr
    report = json.loads(out.stdout)
    assert report["input_complete"] and not report["data_lost"] and report["bytes_unread"] == 0
    assert report["messages"] == 4500 and report["topics"][JS]["messages"] == 3000
    check_rosbag2_layout(out_dir / "run.mcap", 4500)
    original, _ = indexed_mcap_messages(written_run)
    assert sorted(rosbags_messages(out_dir)) == sorted(original)
    # publish times and sequence numbers survive
    with open(written_run, "rb") as a, open(out_dir / "run.mcap", "rb") as b:
        ma = [(m.publish_time, m.sequence) for _s, _c, m in make_reader(a).iter_messages(log_time_order=True)]
        mb = [(m.publish_time, m.sequence) for _s, _c, m in make_reader(b).iter_messages(log_time_order=True)]
    assert ma == mb


def test_refusals_write_nothing(written_run, tmp_path):
    (tmp_path / "empty.mcap").write_bytes(b"")
    (tmp_path / "random.mcap").write_bytes(os.urandom(5000))
    (tmp_path / "header_only.mcap").write_bytes(written_run.read_bytes()[:60])
    with open(tmp_path / "json.mcap", "wb") as f:  # a valid MCAP, but not a rosbag2 one
        from mcap.writer import Writer

        w = Writer(f)
        w.start(profile="", library="test")
        channel = w.register_channel("/j", "json", w.register_schema("t", "jsonschema", b"{}"))
        w.add_message(channel, log_time=1, data=b"{}", publish_time=1)
        w.finish()
    for name, words in (("missing.mcap", "no such file"), ("empty.mcap", "empty file"),
                        ("random.mcap", "not an MCAP file"), ("header_only.mcap", "nothing to recover"),
                        ("json.mcap", "not cdr-encoded")):
        out = run_cli("mcap-recover", str(tmp_path / name))
        assert out.returncode == 2, (name, out.stdout, out.stderr)
        lines = out.stderr.strip().splitlines()
        assert len(lines) == 1 and words in lines[0] and name in lines[0], out.stderr
        assert not list(tmp_path.glob("*.recovered.mcap")) and not (tmp_path / "metadata.yaml").exists()
    target = tmp_path / "taken.mcap"
    target.write_bytes(b"keep")
    out = run_cli("mcap-recover", str(written_run), str(target))
    assert out.returncode == 2 and "exists" in out.stderr and target.read_bytes() == b"keep"
    assert run_cli("mcap-recover", str(written_run), str(target), "--force").returncode == 0




def _killed_recording(tmp_path, ros_domain, total=3200, kill_at=2400, rate_hz=800.0):
    """Publish ``total`` JointStates (header.stamp.nanosec = index) from a test client at ``rate_hz``;
    SIGKILL the recorder after ``kill_at`` of them. Returns (folder, publish wall times, kill time)."""
    from ros_client import RosTestClient
    from sensor_msgs.msg import JointState

    folder = tmp_path / "run"
    rec = start_python_module("recorder", RECORDER, ["--ros-args", "-p", f"output_dir:={folder}",
                                                      "-p", "topics:=[/legs/joint_states]"],
                              ros_environment(ros_domain), tmp_path / "logs")
    client = RosTestClient()
    sent_at = []
    try:
        pub = client.publisher(JS, JointState, depth=1000)
        assert wait_for(lambda: f"subscribed {JS}" in rec.log_text(), 30), rec.log_text()
        assert client.wait_for_subscribers(JS, 1, 30)
        client.spin_for(0.5)
        start = time.monotonic()
        t_kill = None
        for i in range(total):
            due = start + i / rate_hz
            while time.monotonic() < due:
                time.sleep(min(0.001, max(0.0, due - time.monotonic())))
            msg = JointState(name=[f"leg_{k}" for k in range(1, 7)], position=[float(i)] * 6)
            msg.header.stamp.sec, msg.header.stamp.nanosec = 1000, i
            pub.publish(msg)
            sent_at.append(time.monotonic())
            if i + 1 == kill_at:
                os.killpg(rec.popen.pid, signal.SIGKILL)
                t_kill = time.monotonic()
        assert wait_for(lambda: not rec.alive(), 10)
    finally:
        client.close()
        rec.stop()
    return folder, sent_at, t_kill


@pytest.mark.integration
def test_recorder_sigkill_then_recover(ros_domain, tmp_path):
    folder, sent_at, t_kill = _killed_recording(tmp_path, ros_domain)
    files = list(folder.glob("*.mcap"))
    assert len(files) == 1
    assert not (folder / "metadata.yaml").exists()  # a crash leaves no bag metadata
    flushed = flushed_messages(files[0])
    flushed_js = [m for m in flushed if m[0] == JS]
    print(f"flushed before the kill: {len(flushed_js)} of 2400 published; file {files[0].stat().st_size} bytes")
    assert len(flushed_js) >= 1000

    out = run_cli("mcap-recover", str(folder))  # the folder, as a user would after a crash
    print(out.stdout)
    assert out.returncode == 1, out.stdout + out.stderr
    assert "recovered:" in out.stdout and JS in out.stdout and "lost:" in out.stdout
    rebuilt = folder / (files[0].stem + ".recovered.mcap")
    via_rosbags = rosbags_messages(folder)
    via_mcap, summary = indexed_mcap_messages(rebuilt)
    assert len(via_rosbags) >= len(flushed) and len(via_mcap) >= len(flushed)
    assert set(flushed) <= set(via_rosbags) and set(flushed) <= set(via_mcap)
    check_rosbag2_layout(rebuilt, len(via_mcap))

    # Recoverable by design: whatever was published more than flush_period_s (0.5 s) plus
    # 1 s of delivery/scheduling slack before the kill is on disk in a whole chunk.
    store = _store()
    recovered_ids = {store.deserialize_cdr(raw, "sensor_msgs/msg/JointState").header.stamp.nanosec
                     for topic, _t, raw in via_rosbags if topic == JS}
    old_enough = [i for i, t in enumerate(sent_at) if t < t_kill - 1.5]
    assert len(old_enough) > 500
    missing = [i for i in old_enough if i not in recovered_ids]
    assert not missing, f"{len(missing)} messages older than 1.5 s before the kill were lost: {missing[:10]}"
    assert Counter(topic for topic, _t, _d in via_rosbags)[JS] == len(recovered_ids)
