"""Shared fixtures: the robot, and isolated ROS domains for node tests."""

from __future__ import annotations

import gc
import os
import signal
import time
from pathlib import Path

import pytest

from stewart_vibration import load_robot
from stewart_vibration.runtime.processes import claim_ros_domain

# Every process this test session starts inherits this mark in its environment: the left-behind check looks
# at those alone, never at another checkout's run (a CI run, a benchmark) on the same machine, nor at another
# pytest-xdist worker's (each worker of ``./tools/test --fast`` marks its own).
SESSION_MARK_ENV = "STEWART_TEST_SESSION"
if os.environ.get("PYTEST_XDIST_WORKER") or SESSION_MARK_ENV not in os.environ:
    os.environ[SESSION_MARK_ENV] = f"{os.getpid()}-{time.time_ns()}"
_SESSION_MARK = f"{SESSION_MARK_ENV}={os.environ[SESSION_MARK_ENV]}".encode()


def _suite_processes() -> dict[int, str]:
    """pid -> command line of every live process (not a zombie) of this test session (its environment holds
    the session's mark) running this package's code, the test process itself excepted."""
    found = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            if "stewart_vibration" not in cmdline and "stewart-vibration" not in cmdline:
                continue
            state = (entry / "stat").read_text().rsplit(")", 1)[1].split()[0]
            ours = _SESSION_MARK in (entry / "environ").read_bytes().split(b"\0")
        except OSError:  # gone meanwhile, or another user's
            continue
        if state != "Z" and ours:
            found[int(entry.name)] = cmdline.strip()
    return found


LEFT_BEHIND_GRACE_S = 5.0  # wall time a test's processes get to exit after it (s)


def _kill_left_behind(before: set[int]) -> None:
    """Wait up to LEFT_BEHIND_GRACE_S for the package's processes not in ``before`` to exit; kill those that
    do not and fail naming them."""
    deadline = time.monotonic() + LEFT_BEHIND_GRACE_S
    while True:
        left = {pid: cmd for pid, cmd in _suite_processes().items() if pid not in before}
        if not left or time.monotonic() > deadline:
            break
        time.sleep(0.1)
    for pid in left:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    assert not left, "processes left running (killed now): " + "; ".join(
        f"{pid}: {cmd[:160]}" for pid, cmd in left.items())


@pytest.fixture(autouse=True, scope="module")
def no_process_left_behind_by_the_module():
    """A module's shared fixtures stop every process they started (see no_process_left_behind)."""
    before = set(_suite_processes())
    yield
    _kill_left_behind(before)


@pytest.fixture(autouse=True)
def no_process_left_behind():
    """A test that leaves a node or runner process alive fails, and the process is killed: on 2 cores one
    stray 500 Hz node slows every later test that runs the suite."""
    before = set(_suite_processes())
    yield
    _kill_left_behind(before)


@pytest.fixture(autouse=True)
def no_long_garbage_collection_during_an_integration_test(request):
    """The test process's heap grows over the session (hypothesis, recorded messages); a full collection of it
    stalls this process for up to a second, and an integration test that times a node's answer by when it
    arrives here would measure that stall. So the heap is collected before each integration test and what
    lives then is frozen out of the collector (gc.freeze) until the test ends: only the test's own objects are
    scanned while it runs."""
    if request.node.get_closest_marker("integration") is None:
        yield
        return
    gc.collect()
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


@pytest.fixture(scope="session")
def robot():
    return load_robot()


@pytest.fixture
def ros_domain(monkeypatch):
    """A ROS_DOMAIN_ID in 1..101 (localhost discovery) held by this test alone, for it and its children.

    claim_ros_domain locks the ID, so concurrent pytest runs and benchmarks never share a domain.
    """
    domain, lock = claim_ros_domain()
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    yield domain
    lock.close()


@pytest.fixture(scope="module")
def module_ros_domain():
    """Like ros_domain, held by a test module whose tests share one set of node processes."""
    domain, lock = claim_ros_domain()
    mp = pytest.MonkeyPatch()
    mp.setenv("ROS_DOMAIN_ID", str(domain))
    mp.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    yield domain
    mp.undo()
    lock.close()


@pytest.fixture
def second_ros_domain(ros_domain):
    """Another held domain (1..101) for a test that needs two isolated graphs."""
    domain, lock = claim_ros_domain(avoid=(ros_domain,))
    yield domain
    lock.close()


# Hypothesis draws the same examples on every run (CI must not go red by chance; a new find is kept as an
# explicit test case). Set HYPOTHESIS_RANDOM=1 to explore with fresh random examples.
if not os.environ.get("HYPOTHESIS_RANDOM"):
    from hypothesis import settings as _hypothesis_settings

    _hypothesis_settings.register_profile("derandomized", derandomize=True)
    _hypothesis_settings.load_profile("derandomized")
