"""Where the node suite's CPU goes: py-spy profiles of every process of the main job during its vibration, per
node and per kind of work.

Runs the main job with a long vibration (as benchmarks/suite_cpu.py does), and during its steady part samples
each process with ``py-spy record --native`` (native frames: MuJoCo's and rclpy's C code show as themselves; py-spy
pauses a process for each sample, so the rate stays low) while measuring its CPU time. Each sampled stack is given
the kind of its innermost frame that has one:
- physics: MuJoCo (its C library and its Python bindings);
- serialization: the suite's own CDR encoders and decoders (stewart_vibration/messages), rclpy's
  (de)serialization, MCAP record writing and compression;
- rclpy: taking and publishing messages, the executor, timers, rclpy's C++ and the DDS library;
- numpy: numpy (and the linear algebra under it);
- Python glue: everything else (the suite's own Python between those).
Samples of a waiting thread (its innermost frames a wait or a lock) are left out: they use no CPU. Then prints,
per node, its cores and the share of its working samples of each kind (and cores per kind: share x cores).

    .venv/bin/python benchmarks/profile_suite.py [--vibration 40] [--window 25] [--rate 50] [--plant ideal]
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
RULES = (  # (kind, any of these in a frame): the innermost frame that matches one decides
    ("physics", ("mujoco",)),
    ("serialization", ("stewart_vibration/messages/", "serializ", "mcap_log/writer", "zstd", "zstandard",
                       "fastcdr", "mcap_log/bag")),
    ("numpy", ("numpy", "openblas", "lapack", "scipy")),
    ("rclpy", ("rclpy", "librcl", "rmw", "fastdds", "fastrtps", "eprosima")),
)
WAITS = ("pthread_cond_timedwait", "pthread_cond_wait", "pthread_cond_clockwait", "epoll_wait", "poll (", "select (",
         "nanosleep", "sem_timedwait", "sem_wait", "sem_clockwait", "futex", "__lll_lock_wait", "pthread_mutex_lock",
         "PyThread_acquire_lock")  # a blocking acquire in the interpreter: an Event or a queue waited on


def kind_of(stack: str) -> str | None:
    """The kind of work of one sampled stack (frames root first, separated by ';'): the kind of its innermost
    frame that has one, "Python glue" when an innermost Python frame comes first (native frames of the C library
    and the interpreter have none); None for a thread that waits (its innermost frames are a wait: py-spy's native
    mode samples waiting threads too, and they use no CPU)."""
    frames = stack.split(";")
    if any(wait in frame for frame in frames[-3:] for wait in WAITS):
        return None
    for frame in reversed(frames):
        low = frame.lower()
        for kind, marks in RULES:
            if any(mark in low for mark in marks):
                return kind
        if ".py:" in frame:
            return "Python glue"
    return "Python glue"


def read_raw(path: Path) -> Counter:
    """{kind: samples} of a py-spy raw (collapsed stacks) file: one stack per line, then its count."""
    kinds: Counter = Counter()
    if not path.exists():
        return kinds
    for line in path.read_text(errors="replace").splitlines():
        stack, _, count = line.rpartition(" ")
        kind = kind_of(stack) if stack and count.isdigit() else None
        if kind is not None:
            kinds[kind] += int(count)
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
                               str(rate), "--native", "--format", "raw", "--output",
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
        # the Python threads' CPU (working samples over the samples a busy thread gives); the rest of the node's
        # CPU is in threads py-spy does not see (Fast DDS's own receive and event threads)
        row["python_cores"] = min(row["samples"] / (rate * wall), row["cores"])
        row["unsampled_cores"] = row["cores"] - row["python_cores"]
        for kind in KINDS:
            row[kind] = row[kind] / row["samples"] if row["samples"] else None
    return {"exit_code": code, "window_s": wall, "nodes": nodes}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vibration", type=float, default=40.0, help="the vibration's duration (s)")
    ap.add_argument("--window", type=float, default=25.0, help="how long each process is sampled (s)")
    ap.add_argument("--rate", type=int, default=50, help="samples per second")
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
          f"{result['exit_code']}): per node its cores, then the cores of its Python threads by kind of work (share "
          "of their working samples x their cores) and the cores py-spy does not see (DDS's own threads)")
    print(f"| node | cores | {' | '.join(KINDS)} | DDS threads (not sampled) |")
    print("|---|---|" + "---|" * (len(KINDS) + 1))
    nodes = result["nodes"]
    for name, row in sorted(nodes.items(), key=lambda item: -item[1]["cores"]):
        cells = [f"{row[k] * row['python_cores']:.3f} ({100 * row[k]:.0f} %)" if row[k] is not None else "-"
                 for k in KINDS]
        print(f"| {name} | {row['cores']:.3f} | {' | '.join(cells)} | {row['unsampled_cores']:.3f} |")
        if row.get("error"):
            print(f"  {name}: no samples: {row['error']}")
    total = sum(r["cores"] for r in nodes.values())
    per_kind = [sum((r[k] or 0.0) * r["python_cores"] for r in nodes.values()) for k in KINDS]
    per_kind.append(sum(r["unsampled_cores"] for r in nodes.values()))
    print(f"| **all** | **{total:.3f}** | " + " | ".join(f"{v:.3f} ({100 * v / total:.0f} %)" if total else "-"
                                                       for v in per_kind) + " |")
    return 0 if all(r["samples"] for r in result["nodes"].values()) else 1


if __name__ == "__main__":
    sys.exit(main())
