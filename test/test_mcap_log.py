"""Pure MCAP pieces: rosbag2 schema text, QoS YAML, writer/reader, crash-truncated files."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest
import yaml

from stewart_vibration.mcap_log import (
    McapRunWriter,
    QosProfile,
    RunReader,
    dump_qos_profiles,
    full_message_definition,
    has_header_first,
    parse_qos_profiles,
)
from stewart_vibration.mcap_log.files import McapFileError
from stewart_vibration.mcap_log.replay_schedule import ReplayOptions, schedule
from stewart_vibration.messages.cdr import header_stamp_ns

SEP = "=" * 80


def _msg(pkg: str, name: str) -> str:
    """The installed .msg file, read independently of the code under test."""
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    for prefix in [*prefixes, sys.prefix]:
        path = Path(prefix) / "share" / pkg / "msg" / f"{name}.msg"
        if path.is_file():
            return path.read_text()
    pytest.skip(f"{pkg}/msg/{name}.msg not installed")


def _expected(top: tuple[str, str], deps: list[tuple[str, str]]) -> str:
    # rosbag2 layout: top-level text, then per dependency "\n" + 80 '=' + "MSG: pkg/Type".
    text = _msg(*top)
    for pkg, name in deps:
        text += f"\n{SEP}\nMSG: {pkg}/{name}\n" + _msg(pkg, name)
    return text


@pytest.mark.parametrize(
    ("type_name", "top", "deps"),
    [
        (
            "sensor_msgs/msg/JointState",
            ("sensor_msgs", "JointState"),
            [("std_msgs", "Header"), ("builtin_interfaces", "Time")],
        ),
        (
            "geometry_msgs/msg/PoseStamped",
            ("geometry_msgs", "PoseStamped"),
            [
                ("geometry_msgs", "Pose"),
                ("geometry_msgs", "Point"),
                ("geometry_msgs", "Quaternion"),
                ("std_msgs", "Header"),
                ("builtin_interfaces", "Time"),
            ],
        ),
        (
            "diagnostic_msgs/msg/DiagnosticArray",
            ("diagnostic_msgs", "DiagnosticArray"),
            [
                ("diagnostic_msgs", "DiagnosticStatus"),
                ("diagnostic_msgs", "KeyValue"),
                ("std_msgs", "Header"),
                ("builtin_interfaces", "Time"),
            ],
        ),
        ("rosgraph_msgs/msg/Clock", ("rosgraph_msgs", "Clock"), [("builtin_interfaces", "Time")]),
    ],
)
def test_schema_text_is_rosbag2_layout(type_name, top, deps):
    assert full_message_definition(type_name) == _expected(top, deps)


def test_header_detection():
    assert has_header_first("sensor_msgs/msg/JointState")
    assert has_header_first("geometry_msgs/msg/WrenchStamped")
    assert not has_header_first("rosgraph_msgs/msg/Clock")
    assert not has_header_first("rcl_interfaces/msg/Log")


def test_qos_yaml_matches_rosbag2_form_and_round_trips():
    p = QosProfile(history="unknown", depth=0, reliability="best_effort", durability="transient_local")
    text = dump_qos_profiles([p, QosProfile()])
    data = yaml.safe_load(text)
    assert data[0] == {
        "history": "unknown",
        "depth": 0,
        "reliability": "best_effort",
        "durability": "transient_local",
        "deadline": {"sec": 9223372036, "nsec": 854775807},
        "lifespan": {"sec": 9223372036, "nsec": 854775807},
        "liveliness": "automatic",
        "liveliness_lease_duration": {"sec": 9223372036, "nsec": 854775807},
        "avoid_ros_namespace_conventions": False,
    }
    assert parse_qos_profiles(text) == [p, QosProfile()]
    assert dump_qos_profiles([]) == "[]"


def _joint_state_cdr(sec: int, nsec: int) -> bytes:
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_JAZZY)
    JS, Header, Time = (
        ts.types[n] for n in ("sensor_msgs/msg/JointState", "std_msgs/msg/Header", "builtin_interfaces/msg/Time")
    )
    import numpy as np

    msg = JS(
        Header(Time(sec, nsec), "base"),
        ["leg_1"],
        np.array([0.3]),
        np.array([0.0]),
        np.array([10.0]),
    )
    return bytes(ts.serialize_cdr(msg, "sensor_msgs/msg/JointState"))


def test_header_stamp_from_cdr():
    assert header_stamp_ns(_joint_state_cdr(12, 345)) == 12_000_000_345
    assert header_stamp_ns(_joint_state_cdr(0, 0)) is None


def test_writer_reader_rosbags_round_trip(tmp_path):
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    path = tmp_path / "run.mcap"
    w = McapRunWriter(path, chunk_size=2048)
    w.add_topic("/legs/joint_states", "sensor_msgs/msg/JointState", dump_qos_profiles([QosProfile()]))
    for i in range(50):
        w.submit("/legs/joint_states", 1_000 + i * 1_000_000, _joint_state_cdr(5, i + 1))
    stats = w.close()
    assert (stats.received, stats.written, stats.dropped) == (50, 50, 0)
    run = RunReader(path)
    assert run.complete and run.profile == "ros2"
    msgs = list(run.messages())
    assert [m.publish_time for m in msgs] == [5_000_000_000 + i + 1 for i in range(50)]
    meta = yaml.safe_load(run.metadata["rosbag2"]["serialized_metadata"])
    assert meta["version"] == 9 and meta["message_count"] == 50
    assert meta["topics_with_message_count"][0]["message_count"] == 50
    store = get_typestore(Stores.EMPTY)
    with Reader(path) as reader:
        for c in reader.connections:
            store.register(get_types_from_msg(c.msgdef.data, c.msgtype))
        decoded = [store.deserialize_cdr(raw, c.msgtype) for c, _t, raw in reader.messages()]
    assert len(decoded) == 50 and decoded[-1].header.stamp.nanosec == 50


def test_truncated_file_readable_up_to_last_chunk(tmp_path):
    path = tmp_path / "run.mcap"
    w = McapRunWriter(path, chunk_size=1024, flush_period_s=10.0)
    w.add_topic("/legs/joint_states", "sensor_msgs/msg/JointState", "[]")
    for i in range(200):
        w.submit("/legs/joint_states", 1_000 + i, _joint_state_cdr(1, i + 1))
    w.close()
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 2 // 3])
    run = RunReader(cut)
    assert not run.complete and run.truncated
    n = len(list(run.decoded()))
    assert 0 < n < 200 and n == run.message_count()


def test_schedule_rate_offset_and_filters():
    from stewart_vibration.mcap_log.reader import RawMessage

    msgs = [RawMessage("/a" if i % 2 else "/b", "t", 10**9 + i * 10**8, 0, b"") for i in range(10)]
    opts = ReplayOptions(rate=10.0, start_offset_s=0.2, include=("/a", "/b"), exclude=("/b",))
    out = list(schedule(msgs, 10**9, opts))
    assert [m.topic for _d, m in out] == ["/a"] * 4
    assert out[0][0] == pytest.approx(0.01) and out[-1][0] == pytest.approx(0.07)
    with pytest.raises(ValueError):
        ReplayOptions(rate=0.0)


def test_decoding_a_schema_that_is_not_ros2msg_says_so(tmp_path):
    """A channel whose schema is ros2idl (mcap_ros2 decodes ros2msg only) gets McapFileError naming the topic and
    the encoding, not a TypeError from deep inside."""
    from mcap.writer import Writer

    path = tmp_path / "idl.mcap"
    with open(path, "wb") as f:
        writer = Writer(f)
        writer.start(profile="ros2", library="test")
        schema = writer.register_schema("std_msgs/msg/String", "ros2idl", b"module std_msgs { };")
        channel = writer.register_channel("/idl", "cdr", schema)
        writer.add_message(channel, log_time=1, data=b"\x00\x01\x00\x00\x01\x00\x00\x00\x00", publish_time=1)
        writer.finish()
    with pytest.raises(McapFileError, match=r"/idl \[std_msgs/msg/String\].*'ros2idl'"):
        list(RunReader(path).decoded())
