"""The tests' left-behind process check (conftest) looks at this test session's processes only: a process
of the package's started outside the session (another checkout's CI run, a benchmark) is neither reported
nor killed; one started inside is found."""

from __future__ import annotations

import os
import subprocess
import sys
import time

from conftest import SESSION_MARK_ENV, _suite_processes

SLEEPER = [sys.executable, "-c", "import time; time.sleep(60)", "stewart_vibration_left_behind_probe"]


def test_only_this_sessions_processes_are_watched():
    outside_env = {k: v for k, v in os.environ.items() if k != SESSION_MARK_ENV}
    outside = subprocess.Popen(SLEEPER, env=outside_env)
    inside = subprocess.Popen(SLEEPER)
    try:
        # until a child has exec'd, /proc shows the parent's command line and environment (this session's)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and not all(exec_done(p.pid) for p in (outside, inside)):
            time.sleep(0.01)
        found = _suite_processes()
        assert inside.pid in found and outside.pid not in found
    finally:
        for proc in (outside, inside):
            proc.kill()
            proc.wait(10)


def exec_done(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            return SLEEPER[-1].encode() in f.read()
    except OSError:
        return False
