"""mcap_replay's /clock: 100 Hz whatever the message rate, the recorded rate when the run
has a /clock, and a clean exit on stop or at the end (no ERROR, no traceback, exit code 0)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from test_mcap_recover import _cdr, _store

from stewart_vibration.mcap_log import McapRunWriter, QosProfile, dump_qos_profiles
from stewart_vibration.runtime.processes import ros_environment, start_python_module, wait_for

pytestmark = pytest.mark.integration

REPLAY = "stewart_vibration.nodes.mcap_replay_node"
JS = "/legs/joint_states"
T0 = 2_000 * 10**9


def write_source(path, seconds=3.0, msg_hz=1200.0, clock_hz=None):
    """JointStates at ``msg_hz`` (the suite's dense streams) and, with ``clock_hz``, a recorded /clock."""
    w = McapRunWriter(path)
    w.add_topic(JS, "sensor_msgs/msg/JointState", dump_qos_profiles([QosProfile(depth=500)]))
    events = [(T0 + round(i / msg_hz * 1e9), JS, i) for i in range(int(seconds * msg_hz))]
    if clock_hz:
        w.add_topic("/clock", "rosgraph_msgs/msg/Clock", dump_qos_profiles([QosProfile(depth=10)]))
        events += [(T0 + round(k / clock_hz * 1e9), "/clock", k) for k in range(int(seconds * clock_hz) + 1)]
    store = _store()
    clock_type, time_type = store.types["rosgraph_msgs/msg/Clock"], store.types["builtin_interfaces/msg/Time"]
    for t, topic, i in sorted(events):
        if topic == JS:
            w.submit(JS, t, _cdr("sensor_msgs/msg/JointState", i))
        else:
            msg = clock_type(time_type(t // 10**9, t % 10**9))
            w.submit("/clock", t, bytes(store.serialize_cdr(msg, "rosgraph_msgs/msg/Clock")))
    w.close()
    return len([e for e in events if e[1] == "/clock"])


def replay_and_listen(tmp_path, ros_domain, src, params=()):
    """Replay ``src`` to a test client; returns (receive times, clock values ns, MCAP_REPLAY_DONE, log)."""
    from ros_client import RosTestClient
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState

    client = RosTestClient("clock_listener")
    received = []
    client.node.create_subscription(
        Clock, "/clock", lambda m: received.append((time.monotonic(), m.clock.sec * 10**9 + m.clock.nanosec)), 1000)
    client.node.create_subscription(JointState, JS, lambda _m: None, 1000)
    args = ["--ros-args", "-p", f"path:={src}", "-p", "wait_for_subscribers_s:=30", *params]
    rep = start_python_module("replay", REPLAY, args, ros_environment(ros_domain), tmp_path / "logs")
    try:
        assert client.spin_until(lambda: not rep.alive(), 90), rep.log_text()
        client.spin_for(0.3)
    finally:
        client.close()
        code = rep.stop()
    log = rep.log_text()
    assert code == 0, log
    done = json.loads(next(x for x in log.splitlines() if x.startswith("MCAP_REPLAY_DONE "))[17:])
    return np.array([r[0] for r in received]), np.array([r[1] for r in received]), done, log


def rate_hz(times: np.ndarray) -> float:
    """Ticks per second of wall time, from the median spacing of the received ticks: a stall of the
    listener delivers the ticks held meanwhile in a burst, which a count over the whole span reads as a
    faster clock."""
    return 1.0 / float(np.median(np.diff(times)))


def test_published_clock_is_100_hz_not_one_per_message(ros_domain, tmp_path):
    src = tmp_path / "dense.mcap"
    write_source(src, msg_hz=1200.0)
    wall, clock, done, log = replay_and_listen(tmp_path, ros_domain, src, ["-p", "publish_clock:=true"])
    print(f"/clock received: {len(wall)} ticks at {rate_hz(wall):.2f} Hz over {wall[-1] - wall[0]:.3f} s "
          f"while {done['published'][JS]} messages were replayed")
    assert done["published"][JS] == 3600 and done["clock_published"] == len(wall)
    assert abs(rate_hz(wall) - 100.0) <= 5.0
    assert clock[0] == T0 and np.all(np.diff(clock[:-1]) == 10_000_000)  # run time in 10 ms steps
    assert clock[-1] == T0 + round(3599 / 1200 * 1e9)  # the last tick: the last message's time
    assert "ERROR" not in log and "Traceback" not in log


def test_recorded_clock_replayed_at_its_rate(ros_domain, tmp_path):
    src = tmp_path / "with_clock.mcap"
    recorded = write_source(src, msg_hz=1200.0, clock_hz=100.0)
    wall, clock, done, _log = replay_and_listen(tmp_path, ros_domain, src)  # publish_clock false: as recorded
    print(f"recorded /clock replayed: {len(wall)} of {recorded} at {rate_hz(wall):.2f} Hz")
    assert len(wall) == recorded == done["published"]["/clock"] and done["clock_published"] == 0
    assert abs(rate_hz(wall) - 100.0) <= 5.0
    # clock_rate_hz 0: the replay publishes its own /clock at the recorded /clock's rate
    wall, clock, done, _log = replay_and_listen(tmp_path, ros_domain, src,
                                                ["-p", "publish_clock:=true", "-p", "clock_rate_hz:=0"])
    assert "/clock" not in done["published"] and done["clock_rate_hz"] == pytest.approx(100.0)
    assert abs(rate_hz(wall) - 100.0) <= 5.0


def test_stop_mid_replay_is_clean(ros_domain, tmp_path):
    """SIGINT / SIGTERM while publishing 2,000 msg/s and /clock. (Before the fix, about one stop in
    four raced the context shutdown: "[ERROR] replay failed: publisher's context is invalid".)"""
    from ros_client import RosTestClient
    from rosgraph_msgs.msg import Clock

    src = tmp_path / "long.mcap"
    write_source(src, seconds=20.0, msg_hz=2000.0)
    client = RosTestClient("stop_observer")
    ticks = client.subscribe("/clock", Clock)
    try:
        for k, sig in enumerate([signal.SIGINT, signal.SIGTERM] * 2):
            rep = start_python_module(f"replay_{k}", REPLAY,
                                      ["--ros-args", "-p", f"path:={src}", "-p", "publish_clock:=true"],
                                      ros_environment(ros_domain), tmp_path / "logs")
            try:
                ticks.clear()
                assert client.spin_until(lambda: len(ticks) >= 50, 30), rep.log_text()  # mid-replay
                os.killpg(rep.popen.pid, sig)
                assert wait_for(lambda r=rep: not r.alive(), 15)
            finally:
                code = rep.stop()
            log = rep.log_text()
            assert code == 0, log
            assert "ERROR" not in log and "Traceback" not in log and "MCAP_REPLAY_DONE" in log, log
            done = json.loads(log.split("MCAP_REPLAY_DONE ", 1)[1].splitlines()[0])
            assert 0 < done["published"][JS] < 40_000 and done["failure"] is None
    finally:
        client.close()


def test_replay_of_a_bag_directory(ros_domain, tmp_path):
    """path may be the run folder (rosbag2 bag directory), as the recorder and mcap-recover leave it."""
    folder = tmp_path / "bag"
    folder.mkdir()
    write_source(folder / "run.mcap", seconds=0.5, msg_hz=200.0)
    out = subprocess.run([sys.executable, "-m", REPLAY, "--ros-args", "-p", f"path:={folder}"], capture_output=True,
                         text=True, timeout=60, env=ros_environment(ros_domain))
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout.split("MCAP_REPLAY_DONE ", 1)[1])["published"][JS] == 100
