"""Replay timing: the replayer's lateness, the received intervals and the rate-10 speed-up.

    python benchmarks/mcap_replay.py [--messages 300] [--json]

A source run of irregularly spaced JointState messages (4..16 ms apart) is
replayed by the real mcap_replay node into a real mcap_recorder on a private
ROS domain (localhost discovery), at rate 1 and at rate 10. Prints the
replayer's own lateness (p99, max), the error of the received intervals
against the recorded ones (median, p95, p99, max) and the speed-up at rate
10, with the figures this machine is expected to reach (measured on the
2-core VM: lateness p99 < 1 ms, received interval error median < 0.3 ms and
p95 < 1 ms, speed-up 9..11). These are measurements, not pass/fail tests;
test/test_mcap_nodes.py checks the replay's correctness.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test"))

from test_mcap_nodes import replay_into_recorder, write_source_run  # noqa: E402

from stewart_vibration.mcap_log import RunReader  # noqa: E402
from stewart_vibration.runtime.processes import claim_ros_domain, ros_environment  # noqa: E402

EXPECTED = {"lateness_p99_ms": "< 1", "interval_error_median_ms": "< 0.3", "interval_error_p95_ms": "< 1",
            "speedup_rate10": "9 .. 11"}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--messages", type=int, default=300)
    ap.add_argument("--json", action="store_true", help="one JSON line only")
    args = ap.parse_args()
    domain, _lock = claim_ros_domain()
    env = ros_environment(domain)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        src = tmp / "source.mcap"
        t = write_source_run(src, n=args.messages)
        src_bytes = [m.data for m in RunReader(src).messages()]
        done1, t1, data1 = replay_into_recorder(tmp, env, src, 1.0, "rate1")
        done10, t10, data10 = replay_into_recorder(tmp, env, src, 10.0, "rate10")
    err = np.abs(np.diff(t1) - np.diff(t)) / 1e6 if len(t1) == len(t) else np.array([np.nan])
    result = {
        "messages": len(t),
        "bytes_identical": data1 == src_bytes and data10 == src_bytes,
        "lateness_p99_ms": round(done1["lateness_p99_s"] * 1e3, 4),
        "lateness_max_ms": round(done1["lateness_max_s"] * 1e3, 4),
        "lateness_worst": done1["lateness_worst"],
        "interval_error_median_ms": round(float(np.median(err)), 4),
        "interval_error_p95_ms": round(float(np.percentile(err, 95)), 4),
        "interval_error_p99_ms": round(float(np.percentile(err, 99)), 4),
        "interval_error_max_ms": round(float(err.max()), 4),
        "speedup_rate10": round(float((t[-1] - t[0]) / (t10[-1] - t10[0])), 3),
        "lateness_p99_ms_rate10": round(done10["lateness_p99_s"] * 1e3, 4),
    }
    if args.json:
        print(json.dumps(result))
        return 0
    for key, value in result.items():
        target = f"   (expected {EXPECTED[key]})" if key in EXPECTED else ""
        print(f"{key:28s} {value}{target}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
