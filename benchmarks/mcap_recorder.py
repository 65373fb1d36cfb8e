"""Recorder throughput: JointState from another process at >= 5,000 msg/s; received, written, dropped, backlog.

    python benchmarks/mcap_recorder.py [--rate 5000] [--seconds 5]

Runs the real mcap_recorder node and a publisher process on a private ROS
domain (localhost discovery); prints one JSON line.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test"))

from test_mcap_nodes import wait_on_disk  # noqa: E402

from stewart_vibration.mcap_log import RunReader  # noqa: E402
from stewart_vibration.runtime.processes import (  # noqa: E402
    claim_ros_domain,
    ros_environment,
    start_python_module,
    wait_for,
)


def _tagged(text: str, tag: str):
    m = re.search(rf"^{tag} (.*)$", text, re.M)
    return json.loads(m.group(1)) if m else None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rate", type=float, default=5000.0, help="msg/s")
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--domain", type=int, default=None, help="ROS domain (default: a free one in 1..101)")
    args = ap.parse_args()
    if args.domain is None:
        args.domain, _lock = claim_ros_domain()
    env = ros_environment(args.domain)
    # the synthetic publisher is test scaffolding (test/synthetic_run_publisher.py)
    test_dir = str(Path(__file__).resolve().parents[1] / "test")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [test_dir, env.get("PYTHONPATH")]))
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        rec = start_python_module(
            "recorder", "stewart_vibration.nodes.mcap_recorder_node",
            ["--ros-args", "-p", f"output_dir:={tmp / 'out'}", "-p", "topics:=[/legs/joint_states]"], env, tmp,
        )
        count = int(args.rate * args.seconds)
        pub = start_python_module(
            "publisher", "synthetic_run_publisher",
            ["--count", str(count), "--rate", str(args.rate), "--topics", "joint_states", "--fast"], env, tmp,
        )
        waits = {}
        try:
            waits["publisher_finished"] = wait_for(lambda: not pub.alive(), args.seconds + 60)
            pub.stop()
            # the tail has reached the recorder once it is on disk (a transport loss ends the wait at 30 s)
            files = sorted((tmp / "out").glob("*.mcap"))
            waits["tail_on_disk"] = bool(files) and wait_on_disk(files[0], {"/legs/joint_states": count}, 30.0)
            os.killpg(rec.popen.pid, signal.SIGINT)
            waits["recorder_finished"] = wait_for(lambda: not rec.alive(), 30)
        finally:
            rec.stop()
            pub.stop()
        sent = _tagged(pub.log_text(), "SYNTHETIC_SENT")
        stats = _tagged(rec.log_text(), "MCAP_RECORDER_STATS")
        if not sent or not stats:
            print(pub.log_text(), rec.log_text(), file=sys.stderr)
            return 1
        on_disk = RunReader(stats["path"]).topics()
        in_file = sum(t.message_count for t in on_disk if t.topic == "/legs/joint_states")
    result = {
        "publisher_rate_msg_s": round(sent["rate_hz"], 1),
        "sent": sent["counts"]["/legs/joint_states"],
        "received": stats["per_topic"].get("/legs/joint_states", 0),
        "written": stats["written"],
        "in_file": in_file,
        "dropped_by_recorder": stats["dropped"],
        "lost_in_transport": sent["counts"]["/legs/joint_states"] - stats["per_topic"].get("/legs/joint_states", 0),
        "max_backlog_msgs": stats["max_backlog"],
        "waits_ok": waits,
    }
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
