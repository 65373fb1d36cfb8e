"""Runs are rosbag2 bag directories: the recorder writes metadata.yaml beside its .mcap
as rosbag2 writes it (version 9), so rosbags opens the folder; extra files in the folder (logs,
report, summary, an earlier recording) do not disturb it; a crash leaves no metadata.yaml."""

from __future__ import annotations

import json
import os
import signal
from collections import Counter
from pathlib import Path

import pytest
import yaml
from mcap.reader import make_reader
from test_mcap_recover import _cdr, _store

from stewart_vibration.mcap_log import McapRunWriter, QosProfile, RunReader, dump_qos_profiles
from stewart_vibration.mcap_log.bag_metadata import bag_metadata, write_metadata_yaml
from stewart_vibration.mcap_log.output_paths import RECORDED_BY, RECORDED_BY_KEY
from stewart_vibration.runtime.processes import ros_environment, start_python_module, wait_for

RECORDER = "stewart_vibration.nodes.mcap_recorder_node"
PUBLISHER = "synthetic_run_publisher"  # test scaffolding beside this file (on the children's PYTHONPATH)


def _env(ros_domain):
    env = ros_environment(ros_domain)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(Path(__file__).parent), env.get("PYTHONPATH")]))
    return env
JS, POSE = "/legs/joint_states", "/ground_truth/platform_pose"


def _qos_yaml() -> str:
    return dump_qos_profiles([QosProfile(depth=500), QosProfile(depth=10, durability="transient_local")])


def _hash(type_name: str) -> str:
    """The type's RIHS01 hash as rosbags computes it (what DDS discovery reports to the recorder)."""
    return _store().hash_rihs01(type_name)


def _write_ours(folder: Path, marked: bool = False, prefix: str = "") -> dict:
    """A 2-topic file written by our writer, plus its metadata.yaml (``marked``: with the recorder's mark in
    custom_data, as the recorder writes it; ``prefix``: before the topic names)."""
    w = McapRunWriter(folder / "run.mcap")
    js, pose = prefix + JS, prefix + POSE
    w.add_topic(js, "sensor_msgs/msg/JointState", _qos_yaml(), _hash("sensor_msgs/msg/JointState"))
    w.add_topic(pose, "geometry_msgs/msg/PoseStamped", _qos_yaml(), _hash("geometry_msgs/msg/PoseStamped"))
    for i in range(200):
        w.submit(js, 5 * 10**9 + i * 10**7, _cdr("sensor_msgs/msg/JointState", i))
        if i % 4 == 0:
            w.submit(pose, 5 * 10**9 + i * 10**7 + 3, _cdr("geometry_msgs/msg/PoseStamped", i))
    w.close()
    write_metadata_yaml(folder, bag_metadata([w.bag_file()], {RECORDED_BY_KEY: RECORDED_BY} if marked else None))
    return yaml.safe_load((folder / "metadata.yaml").read_text())


def _write_rosbags(folder: Path) -> dict:
    """The same content written by rosbags' own rosbag2 writer (version 9, mcap storage)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.rosbag2.metadata import parse_qos
    store = _store()
    js_def, _ = store.generate_msgdef("sensor_msgs/msg/JointState")
    pose_def, _ = store.generate_msgdef("geometry_msgs/msg/PoseStamped")
    with Writer(folder, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        js = w.add_connection(JS, "sensor_msgs/msg/JointState", msgdef=js_def,
                              rihs01=_hash("sensor_msgs/msg/JointState"), offered_qos_profiles=parse_qos(_qos_yaml()))
        pose = w.add_connection(POSE, "geometry_msgs/msg/PoseStamped", msgdef=pose_def,
                                rihs01=_hash("geometry_msgs/msg/PoseStamped"),
                                offered_qos_profiles=parse_qos(_qos_yaml()))
        for i in range(200):
            w.write(js, 5 * 10**9 + i * 10**7, _cdr("sensor_msgs/msg/JointState", i))
            if i % 4 == 0:
                w.write(pose, 5 * 10**9 + i * 10**7 + 3, _cdr("geometry_msgs/msg/PoseStamped", i))
    return yaml.safe_load((folder / "metadata.yaml").read_text())


def test_metadata_matches_rosbags_version_9_writer(tmp_path):
    ours = _write_ours(tmp_path / "ours")["rosbag2_bagfile_information"]
    theirs = _write_rosbags(tmp_path / "theirs")["rosbag2_bagfile_information"]
    assert ours["ros_distro"] == "jazzy" and theirs["ros_distro"] == "rosbags"
    for meta in (ours, theirs):
        meta.pop("ros_distro")
        names = meta.pop("relative_file_paths")
        assert names == [f["path"] for f in meta["files"]] and len(names) == 1
        for f in meta["files"]:
            f.pop("path")
    assert ours == theirs
    assert ours["version"] == 9 and ours["message_count"] == 250
    qos = ours["topics_with_message_count"][0]["topic_metadata"]["offered_qos_profiles"]
    assert isinstance(qos, list) and qos[1]["durability"] == "transient_local"  # v9: a sequence, not text


def test_yaml_cpp_layout_and_embedded_record(tmp_path):
    _write_ours(tmp_path)
    text = (tmp_path / "metadata.yaml").read_text()
    assert text.startswith("rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: mcap\n")
    for line in ("  topics_with_message_count:\n    - topic_metadata:\n        name: /legs/joint_states\n",
                 "        offered_qos_profiles:\n          - history: keep_last\n            depth: 500\n",
                 "        type_description_hash: RIHS01_",
                 '  compression_format: ""\n', "  relative_file_paths:\n    - run.mcap\n",
                 "  custom_data: ~\n  ros_distro: jazzy\n"):
        assert line in text, line
    with open(tmp_path / "run.mcap", "rb") as f:
        record = {m.name: m.metadata for m in make_reader(f).iter_metadata()}["rosbag2"]
    embedded = yaml.safe_load(record["serialized_metadata"])
    # rosbag2 (storage_mcap read_metadata) decodes this with the version 9 rules: QoS as a sequence
    assert embedded == yaml.safe_load(text)["rosbag2_bagfile_information"]


def _on_disk(path: Path) -> Counter:
    """Messages per topic already flushed to a file the recorder is still writing."""
    try:
        return Counter(m.topic for m in RunReader(path).messages())
    except Exception:  # noqa: BLE001 - momentarily unreadable while written
        return Counter()


def _stats(proc) -> dict:
    line = next(x for x in proc.log_text().splitlines() if x.startswith("MCAP_RECORDER_STATS "))
    return json.loads(line.split(" ", 1)[1])


def _rosbags_counts(folder: Path) -> tuple[Counter, int]:
    from rosbags.highlevel import AnyReader

    with AnyReader([folder]) as reader:
        counts = Counter()
        for conn, _t, raw in reader.messages():
            reader.deserialize(raw, conn.msgtype)
            counts[conn.topic] += 1
        return counts, reader.message_count


@pytest.mark.integration
def test_recorder_folder_is_a_bag_directory_among_other_files(ros_domain, tmp_path):
    env = _env(ros_domain)
    folder = tmp_path / "latest"
    # what a main-job folder holds besides the recording, and an earlier run's bag
    (folder / "logs").mkdir(parents=True)
    (folder / "logs" / "hardware_emulator.log").write_text("log\n")
    (folder / "report").mkdir()
    (folder / "report" / "summary.json").write_text("{}")
    (folder / "summary.json").write_text("{}")
    # an earlier recording (its own topics: a bag lists one QoS per topic): run.mcap + the recorder's metadata.yaml
    _write_ours(folder, marked=True, prefix="/earlier")
    rec = start_python_module("recorder", RECORDER, ["--ros-args", "-p", f"output_dir:={folder}"], env,
                              tmp_path / "proc_logs")
    try:
        assert wait_for(lambda: "recording to" in rec.log_text(), 30), rec.log_text()
        assert not (folder / "metadata.yaml").exists()  # recording: no bag metadata (as after a crash)
        pub = start_python_module("publisher", PUBLISHER, ["--count", "120", "--rate", "200"], env,
                                  tmp_path / "proc_logs")
        assert wait_for(lambda: not pub.alive(), 60), pub.log_text()
        pub.stop()
        new = next(p for p in folder.glob("*.mcap") if p.name != "run.mcap")
        assert wait_for(lambda: _on_disk(new)[JS] >= 120 and _on_disk(new)[POSE] >= 120, 30)  # the tail is in
        os.killpg(rec.popen.pid, signal.SIGINT)
        assert wait_for(lambda: not rec.alive(), 20), rec.log_text()
    finally:
        rec.stop()
    stats = _stats(rec)
    new = Path(stats["path"])
    meta = yaml.safe_load((folder / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    # the earlier recording's file stays listed: the folder is one bag of both recordings
    assert meta["relative_file_paths"] == ["run.mcap", new.name] and new.name != "run.mcap"
    counts, total = _rosbags_counts(folder)
    earlier = {"/earlier" + JS: 200, "/earlier" + POSE: 50}
    expected = Counter(stats["per_topic"]) + Counter(earlier)
    assert counts == expected and total == stats["written"] + 250 == meta["message_count"]
    assert counts[JS] == 120 and counts[POSE] == 120
    listed = {t["topic_metadata"]["name"]: t["message_count"] for t in meta["topics_with_message_count"]}
    assert listed == dict(expected)
    assert "ERROR" not in rec.log_text()


@pytest.mark.integration
def test_second_recording_in_the_same_process_joins_the_bag(ros_domain, tmp_path):
    from ros_client import RosTestClient

    from stewart_vibration_interfaces.msg import Outcome

    env = _env(ros_domain)
    folder = tmp_path / "bag"
    args = ["--ros-args", "-p", f"output_dir:={folder}", "-p", "file_pattern:=part_{stamp}.mcap",
            "-p", "topics:=[/legs/joint_states]"]
    rec = start_python_module("recorder", RECORDER, args, env, tmp_path / "logs")
    client = RosTestClient()
    sent = Counter()
    try:
        for part in range(2):
            if part:
                assert client.start_recording().outcome.code == Outcome.SUCCEEDED
                assert not (folder / "metadata.yaml").exists()
            pub = start_python_module(f"publisher{part}", PUBLISHER, ["--count", "50", "--rate", "200",
                                                                       "--topics", "joint_states"],
                                      env, tmp_path / "logs")
            assert wait_for(lambda p=pub: not p.alive(), 60), pub.log_text()
            pub.stop()
            sent[JS] += 50
            assert client.spin_until(lambda: sum(_on_disk(p)[JS] for p in folder.glob("*.mcap")) >= sent[JS], 30)
            answer = client.stop_recording()
            assert answer.outcome.code == Outcome.SUCCEEDED and (folder / "metadata.yaml").exists()
            assert answer.messages == 50 and answer.bytes == Path(answer.path).stat().st_size
    finally:
        client.close()
        rec.stop()
    meta = yaml.safe_load((folder / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    files = sorted(p.name for p in folder.glob("*.mcap"))
    assert len(files) == 2 and sorted(meta["relative_file_paths"]) == files
    assert [f["message_count"] for f in meta["files"]] == [50, 50]
    counts, total = _rosbags_counts(folder)
    assert counts[JS] == sent[JS] == 100 and total == meta["message_count"]


@pytest.mark.integration
@pytest.mark.slow
def test_main_job_folder_is_a_bag_directory(ros_domain, tmp_path):
    """``stewart-vibration run --out DIR`` leaves DIR a bag directory (beside
    logs/, report/, summary.json) that rosbags opens, and its replay's /clock runs at 100 Hz."""
    import subprocess
    import sys

    from test_mcap_replay_clock import rate_hz, replay_and_listen

    out = tmp_path / "latest"
    proc = subprocess.run([sys.executable, "-m", "stewart_vibration", "run", "--out", str(out), "--domain-id",
                           str(ros_domain), "--duration", "1.6"], capture_output=True, text=True, timeout=600)
    mcaps = list(out.glob("*.mcap"))
    assert len(mcaps) == 1, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert (out / "logs").is_dir() and (out / "summary.json").is_file()
    stats = next(json.loads(x.split(" ", 1)[1]) for x in (out / "logs" / "mcap_recorder.log").read_text().splitlines()
                 if x.startswith("MCAP_RECORDER_STATS "))
    meta = yaml.safe_load((out / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["relative_file_paths"] == [mcaps[0].name] and meta["message_count"] == stats["written"]
    counts, total = _rosbags_counts(out)
    assert dict(counts) == stats["per_topic"] and total == stats["written"]
    assert counts["/clock"] > 100 and counts["/stewart/legs/joint_states"] > 1000
    wall, _clock, done, log = replay_and_listen(tmp_path, ros_domain, out,
                                                ["-p", "publish_clock:=true", "-p", "rate:=4.0",
                                                 "-p", "wait_for_subscribers_s:=2.0"])
    print(f"main-job bag: {total} messages; replay at rate 4: /clock {rate_hz(wall):.2f} Hz, {len(wall)} ticks")
    assert abs(rate_hz(wall) - 100.0) <= 5.0 and done["failure"] is None and "ERROR" not in log
