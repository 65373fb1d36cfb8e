"""Recorder and replay over real DDS: independent readers, signals, SIGKILL, replayed bytes and rate.

Timing figures (replay lateness, interval error, speed-up) are measured by
benchmarks/mcap_replay.py; these tests check correctness only and wait on
what they can observe (files on disk, messages received), never a fixed sleep.
"""

from __future__ import annotations

import json
import os
import signal
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from stewart_vibration.mcap_log import McapRunWriter, QosProfile, RunReader, dump_qos_profiles
from stewart_vibration.runtime.processes import start_python_module, wait_for

pytestmark = pytest.mark.integration

RECORDER = "stewart_vibration.nodes.mcap_recorder_node"
REPLAY = "stewart_vibration.nodes.mcap_replay_node"
PUBLISHER = "synthetic_run_publisher"  # test scaffolding beside this file (on the children's PYTHONPATH)
SUITE = ["/legs/joint_states", "/ground_truth/platform_pose", "/legs/force_estimate", "/diagnostics"]


def _env(ros_domain):
    from stewart_vibration.runtime.processes import ros_environment

    env = ros_environment(ros_domain)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(Path(__file__).parent), env.get("PYTHONPATH")]))
    return env


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


def on_disk(path, topics=None) -> list:
    """Messages already on disk in a file the recorder may still be writing ([] while unreadable)."""
    try:
        return list(RunReader(path).messages(topics))
    except Exception:  # noqa: BLE001 - a file being written can be momentarily unreadable
        return []


def wait_on_disk(path, counts: dict, timeout: float = 30.0) -> bool:
    """Wait until ``path`` holds at least counts[topic] messages of every topic (flushed chunks)."""
    def done():
        got = Counter(m.topic for m in on_disk(path, list(counts)))
        return all(got[t] >= n for t, n in counts.items())

    return wait_for(done, timeout, interval_s=0.1)


def _stamp_ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


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
    count, rate = 150, 300.0
    try:
        sent = _run_publisher(tmp_path, env, count=count, rate=rate)
        # every sent message has reached the recorder once it is on disk (flushed every 0.5 s)
        assert wait_on_disk(_mcap(tmp_path), {t: sent[t] for t in SUITE}), rec.log_text()
        os.killpg(rec.popen.pid, sig)
        assert wait_for(lambda: not rec.alive(), 15), rec.log_text()
    finally:
        rec.stop()
    stats = _tagged_json(rec, "MCAP_RECORDER_STATS")
    assert stats and stats["dropped"] == 0, rec.log_text()
    path = _mcap(tmp_path)
    run = RunReader(path)
    assert run.complete and run.profile == "ros2"
    # /diagnostics also carries the recorder's own status (the file it writes, its counters)
    statuses = [msg.status[0] for _raw, msg in run.decoded(["/diagnostics"])]
    own = [st for st in statuses if st.name.startswith("mcap_recorder")]
    assert own and len(statuses) - len(own) == sent["/diagnostics"]
    assert {kv.key: kv.value for kv in own[-1].values}["path"] == str(path)  # a late UI finds the file here
    assert own[-1].message == f"recording {path}"
    own = len(own)
    for counts in (_counts_rosbags(path), _counts_mcap_ros2(path)):
        for topic in SUITE:
            assert counts[topic] == sent[topic] + (own if topic == "/diagnostics" else 0), (topic, counts, sent)
        assert counts["/rosout"] == stats["per_topic"]["/rosout"]
    topics = {t.topic: t for t in run.topics()}
    js = topics["/legs/joint_states"]
    assert js.type_name == "sensor_msgs/msg/JointState"
    assert "reliability: reliable" in js.offered_qos_profiles
    # publish_time is header.stamp: the publisher's stamps are 1000 s + i / rate (sim-time origin 1000 s)
    decoded = list(run.decoded(["/legs/joint_states"]))
    assert all(raw.publish_time == _stamp_ns(msg.header.stamp) for raw, msg in decoded)
    expected = {1_000_000_000_000 + round(i / rate * 1e9) for i in range(count)}
    assert {raw.publish_time for raw, _msg in decoded} == expected


def test_recorder_sigkill_keeps_completed_chunks(ros_domain, tmp_path):
    """Every message older than the flush period (plus slack) is on disk, while recording and after SIGKILL.

    An observer in this process subscribes to the same topic and notes when each stamp arrived;
    whatever it had received flush_period_s + SLACK_S before a moment must be in the file at that
    moment: checked every 20 messages (0.1 s) while the recorder runs, and in the cut file after the
    kill. SLACK_S covers the writer's poll (flush_period_s / 4) and the recorder receiving later than
    the observer on a loaded machine. Chunks are larger than the run, so only the time flush writes.
    """
    from ros_client import RosTestClient
    from sensor_msgs.msg import JointState

    slack_s, flush_s = 0.5, 0.2
    env = _env(ros_domain)
    rec = _start_recorder(tmp_path, env, extra=["-p", "chunk_size:=1048576", "-p", f"flush_period_s:={flush_s}"])
    pub = client = None
    arrivals = []  # (monotonic receive time, header stamp ns) seen by the observer

    def older_than_flush_missing(now: float, stamps_on_file) -> tuple[int, list]:
        old = {stamp for t, stamp in arrivals if t < now - flush_s - slack_s}
        return len(old), sorted(old - set(stamps_on_file))

    checks = []
    try:
        # 8 s at 200 Hz: the observer may join a few seconds late on a loaded machine
        pub = _run_publisher(tmp_path, env, count=1600, rate=200, wait=False, topics="joint_states")
        # the publisher starts once the recorder is matched; the observer joins after that
        # the recorder can subscribe before it opens its file (start-up discovery, then record_on_start)
        assert wait_for(lambda: "subscribed /legs/joint_states" in rec.log_text() and
                        "recording to" in rec.log_text(), 20), rec.log_text()
        path = _mcap(tmp_path)
        client = RosTestClient("sigkill_observer")
        client.node.create_subscription(
            JointState, "/legs/joint_states",
            lambda m: arrivals.append((time.monotonic(), _stamp_ns(m.header.stamp))), 1000)
        for target in range(20, 401, 20):  # 2 s of the stream from the observer's join, checked every 0.1 s
            assert client.spin_until(lambda n=target: len(arrivals) >= n, 30), (len(arrivals), pub.log_text())
            now = time.monotonic()
            checks.append(older_than_flush_missing(now, [m.publish_time for m in on_disk(path)]))
        assert pub.alive()
        killed_at = time.monotonic()
        os.killpg(rec.popen.pid, signal.SIGKILL)
        assert wait_for(lambda: not rec.alive(), 5)
    finally:
        if client is not None:
            client.close()
        rec.stop()
        if pub is not None:
            pub.stop()
    run = RunReader(_mcap(tmp_path))
    assert not run.complete
    decoded = list(run.decoded(["/legs/joint_states"]))
    assert decoded and all(len(msg.name) == 12 for _raw, msg in decoded)
    on_file = [raw.publish_time for raw, _msg in decoded]
    assert on_file == sorted(on_file) and len(set(on_file)) == len(on_file)
    checks.append(older_than_flush_missing(killed_at, on_file))
    assert checks[-1][0] >= 100, checks  # 2 s observed before the kill, 0.7 s of it too young
    bad = [(i, n, missing[:3]) for i, (n, missing) in enumerate(checks) if missing]
    assert not bad, f"messages older than flush_period_s + {slack_s} s not on disk (check, of, first): {bad}"


def write_source_run(path, n=300, seed=1):
    """A run with irregular spacing (4..16 ms) on one topic, serialized by rclpy itself (also used by
    benchmarks/mcap_replay.py)."""
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



def replay_into_recorder(tmp_path, env, src, rate, name, clock=None):
    """Replay ``src`` at ``rate`` into a fresh recorder; returns (MCAP_REPLAY_DONE report, log times ns,
    recorded bytes). With ``clock`` (a RosTestClient) the replay publishes /clock (publish_clock) and
    the client collects the ticks into clock.received["/clock"]: it is matched to the /clock publisher
    before the recorder starts, and the replay starts only once the recorder subscribes."""
    args = ["--ros-args", "-p", f"path:={src}", "-p", f"rate:={rate}", "-p", "wait_for_subscribers_s:=30.0"]
    rep = rec = None
    try:
        if clock is not None:
            from rosgraph_msgs.msg import Clock

            clock.subscribe("/clock", Clock)
            sub = next(s for s in clock.node.subscriptions if s.topic_name == "/clock")
            rep = start_python_module(f"replay_{name}", REPLAY, [*args, "-p", "publish_clock:=true"], env,
                                      tmp_path / "logs")
            assert clock.spin_until(lambda: sub.get_publisher_count() >= 1, 30), rep.log_text()
        rec = _start_recorder(tmp_path, env, name=name, extra=["-p", "topics:=[/legs/joint_states]"])
        if rep is None:
            rep = start_python_module(f"replay_{name}", REPLAY, args, env, tmp_path / "logs")
        # the observer takes the ticks while the replay runs (its samples may leave with its process)
        finished = clock.spin_until(lambda: not rep.alive(), 60) if clock else wait_for(lambda: not rep.alive(), 60)
        assert finished, rep.log_text()
        done = _tagged_json(rep, "MCAP_REPLAY_DONE")
        assert done and done["failure"] is None and done["published"]["/legs/joint_states"] > 0, rep.log_text()
        # the tail has reached the recorder once it is on disk
        published = done["published"]["/legs/joint_states"]
        assert wait_on_disk(_mcap(tmp_path, name), {"/legs/joint_states": published}), rec.log_text()
    finally:
        for proc in (rep, rec):
            if proc is not None:
                proc.stop()
    run = RunReader(_mcap(tmp_path, name))
    msgs = list(run.messages(["/legs/joint_states"]))
    return done, np.array([m.log_time for m in msgs]), [m.data for m in msgs]


def test_replay_bytes_order_and_rate(ros_domain, tmp_path):
    from ros_client import RosTestClient

    env = _env(ros_domain)
    src = tmp_path / "source.mcap"
    t = write_source_run(src)
    src_bytes = [m.data for m in RunReader(src).messages()]

    done, t1, data1 = replay_into_recorder(tmp_path, env, src, 1.0, "rec_rate1")
    assert data1 == src_bytes  # every recorded message, republished as it is, in order
    err = np.abs(np.diff(t1) - np.diff(t)) / 1e6
    print(f"rate 1: interval error ms median {np.median(err):.3f} p99 {np.percentile(err, 99):.3f} "
          f"max {err.max():.3f}; replay lateness p99 {done['lateness_p99_s'] * 1e3:.3f} ms "
          f"(timing limits: benchmarks/mcap_replay.py)")

    client = RosTestClient("replay_clock_observer")
    try:
        done10, t10, data10 = replay_into_recorder(tmp_path, env, src, 10.0, "rec_rate10", clock=client)
        ticks = client.received["/clock"]
        assert client.spin_until(lambda: len(ticks) >= done10["clock_published"], 20), (len(ticks), done10)
    finally:
        client.close()
    assert data10 == src_bytes
    # The rate reaches the schedule (no wall-clock limit): /clock ticks come every 1 / 100 s of replay
    # time and carry the run time, so at rate 10 consecutive ticks are 0.1 s of run time apart; the last
    # carries the last message's time, and there are as many as 100 Hz fit into the replay's span / 10.
    clock_ns = np.array([_stamp_ns(m.clock) for m in ticks])
    assert len(clock_ns) == done10["clock_published"]
    assert clock_ns[0] == t[0] and clock_ns[-1] == t[-1]
    steps = np.diff(clock_ns)
    assert np.all(np.abs(steps[:-1] - 100_000_000) <= 1) and 0 < steps[-1] <= 100_000_000 + 1
    span_s = (t[-1] - t[0]) / 1e9 / 10.0
    assert len(clock_ns) in (int(span_s * 100) + 1, int(span_s * 100) + 2)
    print(f"rate 10: speed-up {(t[-1] - t[0]) / (t10[-1] - t10[0]):.2f} (measured: benchmarks/mcap_replay.py)")
