"""A topic's true rate: the pure figures from arrival times and stamps, and ``stewart-vibration topic-rate``
over DDS against the emulator's 500 Hz joint states (which leave in bursts of 10 every 20 ms)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from ros_client import node_under_test

from stewart_vibration.messages.topic_rate import topic_rate
from stewart_vibration.runtime.processes import ros_environment


def burst_arrivals(n_bursts: int, burst: int = 10, period_s: float = 0.002):
    """Stamps of a 500 Hz stream and wall arrivals in bursts of ``burst`` (all of a burst within 0.1 ms)."""
    stamps = np.arange(n_bursts * burst) * period_s
    arrivals = np.repeat(np.arange(n_bursts) * burst * period_s, burst) + np.tile(np.arange(burst) * 1e-5, n_bursts)
    return arrivals, stamps


def test_bursts_read_at_the_publishers_rate_and_dropped_samples_are_counted():
    arrivals, stamps = burst_arrivals(50)
    rate = topic_rate(arrivals, stamps)
    assert rate.count == 500 and rate.missing == 0
    assert rate.stamp_hz == pytest.approx(500.0) and rate.period_s == pytest.approx(0.002)
    assert rate.wall_hz == pytest.approx(499 / (arrivals[-1] - arrivals[0]))
    keep = np.ones(500, bool)
    keep[[5, 6, 7, 123, 400]] = False  # a shallow queue's losses: three of one burst, two single ones
    lossy = topic_rate(arrivals[keep], stamps[keep])
    assert lossy.missing == 5 and lossy.period_s == pytest.approx(0.002)
    assert lossy.stamp_hz == pytest.approx(494 / 0.998) and lossy.largest_gap_s == pytest.approx(0.008)


def test_unstamped_and_too_few_messages_say_nothing_they_cannot_know():
    assert topic_rate([]).count == 0 and np.isnan(topic_rate([]).wall_hz)
    one = topic_rate([1.0], [5.0])
    assert one.count == 1 and one.stamped and np.isnan(one.stamp_hz) and one.record()["stamp_hz"] is None
    plain = topic_rate([0.0, 0.5, 1.0])
    assert not plain.stamped and plain.wall_hz == pytest.approx(2.0) and np.isnan(plain.period_s)


@pytest.mark.integration
def test_topic_rate_reads_the_emulators_500_hz_over_dds(ros_domain, tmp_path):
    module = "stewart_vibration.nodes.hardware_emulator_node"
    with node_under_test("emulator", module, ros_domain, tmp_path) as (proc, client):
        command = [sys.executable, "-m", "stewart_vibration.cli.main", "topic-rate", "/legs/joint_states",
                   "--seconds", "3", "--json"]
        done = subprocess.run(command, env=ros_environment(ros_domain), capture_output=True, text=True, timeout=120)
        assert done.returncode == 0, done.stdout + done.stderr + proc.log_text()
        figures = json.loads(done.stdout)
        assert figures["reliability"] == "reliable" and figures["type"] == "sensor_msgs/msg/JointState"
        assert figures["count"] > 500 and figures["missing"] == 0
        assert figures["stamp_hz"] == pytest.approx(500.0, rel=1e-3)
        missing = subprocess.run(command[:4] + ["/no_such_topic", "--wait", "1"], env=ros_environment(ros_domain),
                                 capture_output=True, text=True, timeout=60)
        assert missing.returncode == 2 and "no publisher of /no_such_topic" in missing.stdout
