"""Where the node suite's CPU goes: py-spy profiles of every process of the main job during its vibration, per
node and per kind of work.

Runs the main job with a long vibration (as benchmarks/suite_cpu.py does), and during its steady part samples
each process with ``py-spy record --native --nonblocking`` (native frames: MuJoCo's and rclpy's C code show as
themselves) while measuring its CPU time. Each sampled stack is given the kind of its innermost frame that has
one:
- physics: MuJoCo (its C library and its Python bindings);
- serialization: the suite's own CDR encoders and decoders (stewart_vibration/messages), rclpy's
  (de)serialization, MCAP record writing and compression;
- rclpy: taking and publishing messages, the executor, timers, waits inside rclpy and the DDS library;
- numpy: numpy (and the linear algebra under it);
- Python glue: everything else (the suite's own Python between those).
Then prints, per node, its cores and the share of its samples of each kind (and cores per kind: share x cores).

    .venv/bin/python benchmarks/profile_suite.py [--vibration 30] [--window 10] [--rate 200] [--plant ideal]
        [--json] [--keep DIR]

Needs py-spy (requirements-dev.txt) and the permission to read another process's memory (root, or ptrace_scope
0). Exit code 0 when every node was profiled.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from suite_cpu import children, cpu_seconds, process_name, start_vibrating  # noqa: E402 - not a package

KINDS = ("physics", "serialization", "rclpy", "numpy", "Python glue")
RULES = (  # (kind, any of these in a frame), the innermost frame that matches one decides
    ("physics", ("mujoco",)),
    ("serialization", ("stewart_vibration/messages/", "serializ", "mcap_log/writer", "zstd", "zstandard",
                       "cdr", "mcap_log/bag")),
    ("numpy", ("numpy", "libopenblas", "lapack", "blas")),
    ("rclpy", ("rclpy", "rcl_", "rmw", "fastdds", "fastrtps", "eprosima", "librcl", "_rclpy", "pthread_cond",
               "epoll", "futex")),
)


def kind_of(stack: str) -> str:
    """The kind of work of one sampled stack (frames root first, separated by ';')."""
    for frame in reversed(stack.split(";")):
        low = frame.lower()
        for kind, marks in RULES:
            if any(mark in low for mark in marks):
                return kind
    return "Python glue"


def read_raw(path: Path) -> Counter:
    """{kind: samples} of a py-spy raw (collapsed stacks) file: one stack per line, then its count."""
    kinds: Counter = Counter()
    if not path.exists():
        return kinds
    for line in path.read_text(errors="replace").splitlines():
        stack, _, count = line.rpartition(" ")
        if stack and count.isdigit():
            kinds[kind_of(stack)] += int(count)
    return kinds


def profile_run(vibration_s: float, window_s: float, rate: int, plant: str, out: Path, settle_s: float = 3.0) -> dict:
    """The main job vibrating for ``vibration_s`` (s); after ``settle_s`` of its vibration every process sampled
    for ``window_s`` (s). Returns {node: {"cores", "samples", kind: share}} and the run's exit code."""
    proc, _lines, _domain, lock = start_vibrating(vibration_s, out, plant)
    time.sleep(settle_s)
    pids = [proc.pid, *children(proc.pid)]
    names = {pid: ("runner" if pid == proc.pid else process_name(pid)) for pid in pids}
    spy = shutil.which("py-spy") or str(Path(sys.executable).parent / "py-spy")
    files = {pid: out / f"profile_{names[pid]}_{pid}.txt" for pid in pids}
    cpu0, wall0 = {pid: cpu_seconds(pid) for pid in pids}, time.monotonic()
    spies = [subprocess.Popen([spy, "record", "--pid", str(pid), "--duration", str(int(window_s)), "--rate",
                               str(rate), "--native", "--nonblocking", "--format", "raw", "--output",
                               str(files[pid])], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
             for pid in pids]
    errors = [s.communicate(timeout=window_s + 60)[1].decode(errors="replace") for s in spies]
    cpu1, wall = {pid: cpu_seconds(pid) for pid in pids}, time.monotonic() - wall0
    code = proc.wait(timeout=600)
    lock.close()
    nodes: dict = {}
    for pid, error in zip(pids, errors, strict=True):
        kinds = read_raw(files[pid])
        total = sum(kinds.values())
        before, after = cpu0[pid], cpu1[pid]
        cores = (after - before) / wall if before is not None and after is not None else None
        row = nodes.setdefault(names[pid], {"cores": 0.0, "samples": 0, **{k: 0 for k in KINDS}})
        row["cores"] += cores or 0.0
        row["samples"] += total
        for kind in KINDS:
            row[kind] += kinds.get(kind, 0)
        if not total:
            row["error"] = error.strip()[-300:]
    for row in nodes.values():
        for kind in KINDS:
            row[kind] = row[kind] / row["samples"] if row["samples"] else None
    return {"exit_code": code, "window_s": wall, "nodes": nodes}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vibration", type=float, default=30.0, help="the vibration's duration (s)")
    ap.add_argument("--window", type=float, default=10.0, help="how long each process is sampled (s)")
    ap.add_argument("--rate", type=int, default=200, help="samples per second")
    ap.add_argument("--plant", default="ideal")
    ap.add_argument("--keep", type=Path, default=None, help="keep the run folder and the raw profiles here")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = args.keep or Path(tmp) / "run"
        out.mkdir(parents=True, exist_ok=True)
        result = profile_run(args.vibration, args.window, args.rate, args.plant, out)
    if args.json:
        print(json.dumps(result, indent=2))
        return 0 if all(r["samples"] for r in result["nodes"].values()) else 1
    print(f"py-spy profiles over {result['window_s']:.1f} s of the vibration ({args.plant} plant; the run exited "
          f"{result['exit_code']}): share of each node's samples per kind of work, and cores (share x the node's "
          "cores)")
    print(f"| node | cores | {' | '.join(KINDS)} |")
    print("|---|---|" + "---|" * len(KINDS))
    total = 0.0
    for name, row in sorted(result["nodes"].items(), key=lambda item: -item[1]["cores"]):
        total += row["cores"]
        cells = [f"{100 * row[k]:.0f} % ({row[k] * row['cores']:.3f})" if row[k] is not None else "-" for k in KINDS]
        print(f"| {name} | {row['cores']:.3f} | {' | '.join(cells)} |")
        if row.get("error"):
            print(f"  {name}: no samples: {row['error']}")
    per_kind = {k: sum((r[k] or 0.0) * r["cores"] for r in result["nodes"].values()) for k in KINDS}
    print(f"| **all** | **{total:.3f}** | " + " | ".join(f"{100 * v / total:.0f} % ({v:.3f})" if total else "-"
                                                       for v in per_kind.values()) + " |")
    return 0 if all(r["samples"] for r in result["nodes"].values()) else 1


if __name__ == "__main__":
    sys.exit(main())
