#!/usr/bin/env python3
"""Mutation check of the core math: flip one operator or constant at a time, see whether the tests notice.

    .venv/bin/python tools/mutation_check.py [--max-mutants 150] [--seed 14] [--module NAME ...] [--json FILE]

The package is copied to a temporary directory (with a link to config/), one
mutant at a time is written into the copy, and the fast unit tests that cover
that module run against it (``pytest -x -q -m "not integration"``,
PYTHONPATH pointed at the copy, PYTHONSAFEPATH so the checkout itself is not
imported, one thread). A mutant is killed when the tests fail (or error, or
time out) and survives when they pass. No dependency beyond the test suite's.

Mutations (one token each, found with ``tokenize`` so comments and strings are
never touched): arithmetic + <-> - (unary too), binary * <-> /; comparisons < <-> <=, > <-> >=,
== <-> !=; boolean and <-> or; numeric constants 0 -> 1, integer n -> n + 1,
float x -> 2 x. Mutants that do not compile are skipped. Mutants are drawn at
random (fixed seed) from every site, spread over the modules in proportion
to their sites (at least a few each), up to --max-mutants.

Prints a table (module, mutants, killed, survived) and every survivor as
``module:line  original -> mutated``; exit code 0 (the survivors are a
report, not a failure).
"""

from __future__ import annotations

import argparse
import io
import json
import os
import random
import shutil
import subprocess
import sys
import tempfile
import time
import tokenize
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "stewart_vibration"
PACKAGE_DIR = ROOT / PACKAGE  # the ament_python package: setup.py, config/ and the module

# core modules (glob relative to the package; the first pattern that matches a file wins) -> the fast unit
# tests that cover them, most telling first (files that do not exist are left out)
VIBRATION_TESTS = ["test_vibration_decompose.py", "test_vibration_superpose.py", "test_vibration_signals.py",
                   "test_vibration_limits.py", "test_vibration_streaming.py"]
COVERAGE = [
    ("kinematics/ik.py", ["test_kinematics.py", "test_errors.py", "test_dynamics_kinematics.py"]),
    ("kinematics/fk.py", ["test_kinematics.py", "test_errors.py"]),
    ("kinematics/limits.py", ["test_kinematics.py", "test_errors.py"]),
    ("kinematics/geometry.py", ["test_kinematics.py", "test_dynamics_kinematics.py"]),
    ("kinematics/jacobian.py", ["test_kinematics.py", "test_dynamics_kinematics.py"]),
    ("kinematics/fk_scalar.py", ["test_kinematics.py"]),
    ("kinematics/legs.py", ["test_dynamics_kinematics.py", "test_estimation.py", "test_dynamics_forces.py"]),
    ("dynamics/newton_euler.py", ["test_dynamics_forces.py", "test_estimation.py", "test_mujoco_model.py"]),
    ("kinematics/rotations.py", ["test_rotations.py", "test_kinematics.py", "test_dynamics_kinematics.py"]),
    ("vibration/paper_study.py", ["test_vibration_paper_cli.py"]),
    ("vibration/streaming.py", ["test_vibration_streaming.py"]),
    ("vibration/settings.py", ["test_vibration_settings.py", "test_vibration_streaming.py"]),
    ("vibration/feasibility.py", ["test_vibration_limits.py", "test_vibration_streaming.py"]),
    ("vibration/*.py", VIBRATION_TESTS),
    ("estimation/motion.py", ["test_estimation.py"]),
    ("analysis/fits.py", ["test_analysis.py", "test_mcap_report.py"]),
    ("motion/paths.py", ["test_motion_profiles.py", "test_tissue.py"]),
    ("motion/profiles.py", ["test_motion_profiles.py"]),
    ("motion/force_guard.py", ["test_force_guard.py", "test_tissue.py"]),
    ("motion/guarded_move.py", ["test_force_guard.py", "test_tissue.py"]),
    ("motion/load_prediction.py", ["test_force_guard.py", "test_tissue.py"]),
    ("motion/stop_planning.py", ["test_force_guard.py", "test_tissue.py"]),
    ("motion/estimate_watch.py", ["test_force_guard.py", "test_tissue.py"]),
    ("motion/guard_status.py", ["test_force_guard.py", "test_tissue.py", "test_messages_status_values.py"]),
    ("motion/guard_supervisor.py", ["test_force_guard.py", "test_tissue.py"]),
    ("dynamics/tissue*.py", ["test_tissue.py"]),
    ("emulation/vibration_buffer.py", ["test_emulation_vibration_buffer.py", "test_vibration_streaming.py"]),
    ("emulation/strut_trajectory.py", ["test_hostile_inputs.py", "test_emulation_emulator.py"]),
    ("estimation/session.py", ["test_estimation_session.py", "test_estimation.py"]),
]
SWAPS = {"+": "-", "-": "+", "*": "/", "/": "*", "<": "<=", "<=": "<", ">": ">=", ">=": ">", "==": "!=",
         "!=": "==", "and": "or", "or": "and"}
MIN_PER_MODULE = 4


@dataclass(frozen=True)
class Mutant:
    module: str  # path relative to the package
    line: int
    col: int
    original: str
    mutated: str


def module_files(package_dir: Path, only: list[str] | None) -> dict[str, list[str]]:
    """Core modules that exist (relative paths) -> their test files."""
    out = {}
    for pattern, tests in COVERAGE:
        for path in sorted(package_dir.glob(pattern)):
            rel = path.relative_to(package_dir).as_posix()
            if rel in out or path.name == "__init__.py" or (only and rel not in only and path.stem not in only):
                continue
            existing = [t for t in tests if (ROOT / "test" / t).is_file()]
            if existing:
                out[rel] = existing
    return out


def _mutated_number(text: str) -> str | None:
    try:
        value = int(text, 0)
    except ValueError:
        try:
            value = float(text)
        except ValueError:
            return None  # complex literals and the like
        return "1.0" if value == 0 else repr(2 * value)
    return "1" if value == 0 else str(value + 1)


def mutation_sites(module: str, source: str) -> list[Mutant]:
    """Every single-token mutation of ``source`` that still compiles."""
    sites = []
    lines = source.splitlines(keepends=True)
    prev = None  # previous significant token
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type in (tokenize.NL, tokenize.NEWLINE, tokenize.COMMENT, tokenize.INDENT, tokenize.DEDENT):
            continue
        before, prev = prev, tok
        if tok.type == tokenize.OP and tok.string in ("*", "/") and not _ends_operand(before):
            continue  # *args, keyword-only and positional-only markers: not arithmetic
        if tok.type == tokenize.OP and tok.string in SWAPS:
            new = SWAPS[tok.string]
        elif tok.type == tokenize.NAME and tok.string in ("and", "or"):
            new = SWAPS[tok.string]
        elif tok.type == tokenize.NUMBER:
            new = _mutated_number(tok.string)
        else:
            continue
        if new is None:
            continue
        (row, col), (_, end) = tok.start, tok.end
        line = lines[row - 1]
        mutated = source_with(lines, row, line[:col] + new + line[end:])
        try:
            compile(mutated, module, "exec")
        except SyntaxError:
            continue  # e.g. * in *args
        sites.append(Mutant(module, row, col, tok.string, new))
    return sites


def _ends_operand(tok) -> bool:
    """True if ``tok`` can end the left operand of a binary operator."""
    if tok is None:
        return False
    if tok.type in (tokenize.NUMBER, tokenize.STRING):
        return True
    if tok.type == tokenize.NAME:
        return tok.string not in ("lambda", "in", "not", "and", "or", "return", "yield", "else", "if")
    return tok.string in (")", "]", "}")


def source_with(lines: list[str], row: int, new_line: str) -> str:
    return "".join(lines[: row - 1]) + new_line + "".join(lines[row:])


def apply(source: str, m: Mutant) -> str:
    lines = source.splitlines(keepends=True)
    line = lines[m.line - 1]
    assert line[m.col: m.col + len(m.original)] == m.original, (m, line)
    return source_with(lines, m.line, line[: m.col] + m.mutated + line[m.col + len(m.original):])


def pick(sites: dict[str, list[Mutant]], budget: int, rng: random.Random) -> list[Mutant]:
    """About ``budget`` mutants: each module in proportion to its sites (rounded down), at least MIN_PER_MODULE."""
    total = sum(len(s) for s in sites.values()) or 1
    chosen = []
    for ms in sites.values():
        share = max(MIN_PER_MODULE, budget * len(ms) // total)
        chosen += rng.sample(ms, min(share, len(ms)))
    return sorted(chosen, key=lambda m: (m.module, m.line, m.col))


def run_tests(copy_root: Path, tests: list[str], timeout: float) -> tuple[str, float]:
    """'passed', 'failed' or 'timeout' of the tests against the copy; wall seconds."""
    env = dict(os.environ, PYTHONPATH=str(copy_root), PYTHONSAFEPATH="1", PYTHONDONTWRITEBYTECODE="1",
               STEWART_VIBRATION_THREADS="1", OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1",
               STEWART_VIBRATION_CONFIG_DIR=str(PACKAGE_DIR / "config"))
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-m", "not integration", "-p", "no:cacheprovider",
           "--rootdir", str(ROOT), *[str(ROOT / "test" / t) for t in tests]]
    start = time.monotonic()
    try:
        proc = subprocess.run(cmd, cwd=copy_root, env=env, capture_output=True, text=True, timeout=timeout,
                              preexec_fn=lambda: os.nice(10))
    except subprocess.TimeoutExpired:
        return "timeout", time.monotonic() - start
    return ("passed" if proc.returncode == 0 else "failed"), time.monotonic() - start


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--max-mutants", type=int, default=150)
    ap.add_argument("--seed", type=int, default=14)
    ap.add_argument("--module", action="append", help="only this core module (e.g. dynamics.py); repeatable")
    ap.add_argument("--json", help="write the full result (every mutant) to this file")
    ap.add_argument("--list", action="store_true", help="only count the mutation sites per module (and their tests)")
    args = ap.parse_args()

    src_pkg = PACKAGE_DIR / PACKAGE
    modules = module_files(src_pkg, args.module)
    sources = {m: (src_pkg / m).read_text() for m in modules}  # the snapshot every mutant is made from
    sites = {m: mutation_sites(m, sources[m]) for m in modules}
    if args.list:
        for m, s in sites.items():
            print(f"{m:32s} {len(s):4d} sites   {' '.join(modules[m])}")
        return 0
    chosen = pick(sites, args.max_mutants, random.Random(args.seed))

    with tempfile.TemporaryDirectory(prefix="mutation_") as tmp:
        copy_root = Path(tmp)
        shutil.copytree(src_pkg, copy_root / PACKAGE, ignore=shutil.ignore_patterns("__pycache__"))
        for module, text in sources.items():  # the tree may change under us (shared checkout)
            (copy_root / PACKAGE / module).write_text(text)
        (copy_root / "config").symlink_to(PACKAGE_DIR / "config")
        baseline = {}
        for module in sorted({m.module for m in chosen}):
            status, seconds = run_tests(copy_root, modules[module], timeout=600)
            if status != "passed":
                print(f"baseline tests of {module} do not pass unmutated ({status}); skipping its mutants",
                      file=sys.stderr)
                continue
            baseline[module] = seconds
        results = []
        for k, m in enumerate(chosen, 1):
            if m.module not in baseline:
                continue
            path = copy_root / PACKAGE / m.module
            original = path.read_text()
            path.write_text(apply(original, m))
            try:
                status, seconds = run_tests(copy_root, modules[m.module], timeout=max(60.0, 5 * baseline[m.module]))
            finally:
                path.write_text(original)
            results.append((m, status, seconds))
            mark = "survived" if status == "passed" else "killed"
            print(f"[{k}/{len(chosen)}] {m.module}:{m.line} {m.original!r} -> {m.mutated!r}: {mark} "
                  f"({status}, {seconds:.1f} s)", flush=True)

    table = {}
    for m, status, _s in results:
        row = table.setdefault(m.module, [0, 0, 0])
        row[0] += 1
        row[1 if status != "passed" else 2] += 1
    print(f"\n{'module':32s} {'mutants':>8s} {'killed':>8s} {'survived':>9s}")
    for module, (n, killed, survived) in sorted(table.items()):
        print(f"{module:32s} {n:8d} {killed:8d} {survived:9d}")
    totals = [sum(r[i] for r in table.values()) for i in range(3)]
    print(f"{'total':32s} {totals[0]:8d} {totals[1]:8d} {totals[2]:9d}")
    survivors = [m for m, status, _s in results if status == "passed"]
    if survivors:
        print("\nsurvivors:")
        for m in survivors:
            line = sources[m.module].splitlines()[m.line - 1].strip()
            print(f"  {m.module}:{m.line}  {m.original} -> {m.mutated}    | {line}")
    if args.json:
        Path(args.json).write_text(json.dumps(
            {"seed": args.seed, "table": table, "mutants": [
                {"module": m.module, "line": m.line, "col": m.col, "original": m.original, "mutated": m.mutated,
                 "status": status, "seconds": round(s, 2)} for m, status, s in results]}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
