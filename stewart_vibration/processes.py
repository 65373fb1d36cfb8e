"""Start and stop node processes (no rclpy): isolated ROS domains, clean teardown.

Used by the bring-up and by integration tests. Each child runs in its own
process group so a stop reaches everything it spawned; stop() sends SIGINT,
then SIGTERM, then SIGKILL, each after a grace period. A child also gets
SIGTERM if its parent dies (even by SIGKILL), so nothing is orphaned.
"""

from __future__ import annotations

import fcntl
import os
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path


def ros_environment(domain_id: int, base: dict | None = None) -> dict:
    """Environment for a child on ``domain_id``, discovery limited to localhost."""
    env = dict(os.environ if base is None else base)
    env["ROS_DOMAIN_ID"] = str(int(domain_id))
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.pop("ROS_LOCALHOST_ONLY", None)
    env["PYTHONUNBUFFERED"] = "1"
    prefixes = [p for p in env.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    if sys.prefix not in prefixes:
        env["AMENT_PREFIX_PATH"] = os.pathsep.join([sys.prefix, *prefixes])
    return env


# ROS domain IDs the suite picks for itself stay within 1..101: above 101 Fast DDS ports fall in the
# ephemeral range and discovery fails intermittently; 0 is the users' default domain.
DOMAIN_RANGE = range(1, 102)
_DOMAIN_LOCK_DIR = Path(tempfile.gettempdir()) / "stewart_vibration_ros_domains"


def claim_ros_domain(avoid: tuple[int, ...] = ()):
    """(domain id, open lock file) of a ROS domain in 1..101 that no other process of this machine holds.

    Held by an exclusive lock file (flock) until the returned file is closed or the process exits, so
    concurrent runs (tests, benchmarks, the main job) never share a domain. Raises RuntimeError if all are taken.
    """
    _DOMAIN_LOCK_DIR.mkdir(exist_ok=True)
    ids = [d for d in DOMAIN_RANGE if d not in avoid]
    start = os.getpid() % len(ids)
    for domain in ids[start:] + ids[:start]:
        handle = open(_DOMAIN_LOCK_DIR / f"{domain}.lock", "w")  # noqa: SIM115 - held until released
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.close()
            continue
        return domain, handle
    raise RuntimeError(f"no free ROS domain in {DOMAIN_RANGE.start}..{DOMAIN_RANGE.stop - 1}")


@dataclass
class NodeProcess:
    """One child process with its log file."""

    name: str
    popen: subprocess.Popen
    log_path: Path
    _log_file: object = field(repr=False, default=None)

    def alive(self) -> bool:
        return self.popen.poll() is None

    def log_text(self) -> str:
        try:
            return self.log_path.read_text(errors="replace")
        except OSError:
            return ""

    def stop(self, grace_s: float = 5.0) -> int | None:
        """SIGINT, then SIGTERM, then SIGKILL to the process group; returns the exit code."""
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            if not self.alive():
                break
            try:
                os.killpg(self.popen.pid, sig)
            except ProcessLookupError:
                break
            try:
                self.popen.wait(timeout=grace_s)
            except subprocess.TimeoutExpired:
                continue
        if self._log_file is not None:
            self._log_file.close()
            self._log_file = None
        return self.popen.poll()


_PR_SET_PDEATHSIG = 1


def _child_setup() -> None:
    """In the child before exec: own session (a stop reaches its whole group) and SIGTERM when
    the parent dies, even by SIGKILL, so no node outlives the bring-up (Linux prctl)."""
    os.setsid()
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
    except (OSError, AttributeError):  # not Linux: the parent's stop() still cleans up
        pass


def start_python_module(
    name: str, module: str, args: list[str], env: dict, log_dir: Path
) -> NodeProcess:
    """Run ``python -m module args`` in a new process group, output to log_dir/name.log."""
    log_dir.mkdir(parents=True, exist_ok=True)
    log_path = log_dir / f"{name}.log"
    log_file = open(log_path, "w")  # noqa: SIM115 - closed in stop()
    popen = subprocess.Popen(
        [sys.executable, "-m", module, *args],
        env=env,
        stdout=log_file,
        stderr=subprocess.STDOUT,
        stdin=subprocess.DEVNULL,
        preexec_fn=_child_setup,
    )
    return NodeProcess(name, popen, log_path, log_file)


def wait_for(predicate, timeout_s: float, interval_s: float = 0.05) -> bool:
    """Poll ``predicate()`` until it is true or ``timeout_s`` passes."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(interval_s)
    return bool(predicate())
