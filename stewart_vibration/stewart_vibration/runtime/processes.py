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
from collections.abc import MutableMapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

from ..errors import ConfigError
from ..install import find_config_file, prepend_interpreter_prefix

# Fast DDS transport profile of the suite (docs/security.md): STEWART_DDS_PROFILE = "loopback"
# (default: config/fastdds_localhost.xml, UDPv4 on 127.0.0.1 only, no shared memory), "multihost"
# (Fast DDS defaults: every interface, multicast discovery on the subnet) or the path of a Fast DDS
# XML profile file (its default participant profile is used as it is).
DDS_PROFILE_ENV = "STEWART_DDS_PROFILE"
LOOPBACK_PROFILE_FILE = "fastdds_localhost.xml"
# Fast DDS 2.x (Jazzy) reads FASTRTPS_DEFAULT_PROFILES_FILE only; 3.x reads FASTDDS_DEFAULT_PROFILES_FILE.
_PROFILE_FILE_VARS = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")


def loopback_profile_path(config_dir: str | os.PathLike | None = None) -> Path:
    """config/fastdds_localhost.xml: in ``config_dir`` if given, else the first of the package's config
    directories that has it (``install.config_dirs``: the source tree's config/, then
    share/stewart_vibration/config of an install prefix). Raises FileNotFoundError naming the places
    searched."""
    return find_config_file(LOOPBACK_PROFILE_FILE, None if config_dir is None else [config_dir])


def dds_environment(choice: str | None = None, config_dir: str | os.PathLike | None = None) -> dict:
    """Environment variables (value None = unset) that select the suite's DDS transport profile.

    ``choice`` is the value of STEWART_DDS_PROFILE: empty/None or "loopback" (default), "multihost",
    or the path of a Fast DDS XML profile file. For loopback and a file, the profile file goes to
    FASTRTPS_/FASTDDS_DEFAULT_PROFILES_FILE and ROS_AUTOMATIC_DISCOVERY_RANGE is SYSTEM_DEFAULT: with
    LOCALHOST, rmw_fastrtps would add its own UDPv4 transport listening on 0.0.0.0 to the profile's.
    SKIP_DEFAULT_XML_FILE=1 keeps a stray DEFAULT_FASTRTPS_PROFILES.xml in the working directory from
    changing it; ROS_LOCALHOST_ONLY is unset (its 1 would mean LOCALHOST). "multihost" unsets the
    profile files and asks for SUBNET discovery (ROS_STATIC_PEERS apply). Raises ConfigError (a
    ValueError) for any other choice: a typo never falls back to all interfaces."""
    choice = (choice or "").strip()
    if choice.lower() == "multihost":
        env: dict = dict.fromkeys(_PROFILE_FILE_VARS)
        env["ROS_LOCALHOST_ONLY"] = None
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SUBNET"
        return env
    if choice.lower() in ("", "loopback"):
        path = loopback_profile_path(config_dir)
    else:
        path = Path(choice).expanduser()
        if not path.is_file():
            raise ConfigError(f"{DDS_PROFILE_ENV}={choice!r}: not 'loopback', 'multihost' or an existing "
                             "Fast DDS XML profile file")
        path = path.resolve()
    env = dict.fromkeys(_PROFILE_FILE_VARS, str(path))
    env["SKIP_DEFAULT_XML_FILE"] = "1"
    env["ROS_LOCALHOST_ONLY"] = None
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SYSTEM_DEFAULT"
    return env


def apply_environment(env: MutableMapping[str, str], changes: dict) -> MutableMapping[str, str]:
    """``env`` with ``changes`` applied in place (a None value removes the variable); returns env."""
    for key, value in changes.items():
        if value is None:
            env.pop(key, None)
        else:
            env[key] = value
    return env


def ros_environment(domain_id: int, base: dict | None = None) -> dict:
    """Environment for a child on ``domain_id`` with the suite's DDS profile (``dds_environment`` of
    $STEWART_DDS_PROFILE in ``base``: loopback only by default)."""
    env = dict(os.environ if base is None else base)
    env["ROS_DOMAIN_ID"] = str(int(domain_id))
    apply_environment(env, dds_environment(env.get(DDS_PROFILE_ENV)))
    env["PYTHONUNBUFFERED"] = "1"
    prepend_interpreter_prefix(env)
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
    _log_file: IO[str] | None = field(repr=False, default=None)
    command: tuple = field(repr=False, default=())  # (module, args, env) to start it again

    def alive(self) -> bool:
        """True while the process has not exited."""
        return self.popen.poll() is None

    def restart(self) -> NodeProcess:
        """Start the same module with the same arguments and environment (the log file is appended to)."""
        module, args, env = self.command
        if self._log_file is not None:
            self._log_file.close()
            self._log_file = None
        return start_python_module(self.name, module, list(args), env, self.log_path.parent, append=True)

    def log_text(self) -> str:
        """The process's log so far ("" if the file cannot be read)."""
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
    name: str, module: str, args: list[str], env: dict, log_dir: Path, append: bool = False
) -> NodeProcess:
    """Run ``python -m module args`` in a new process group, output to log_dir/name.log."""
    log_dir.mkdir(parents=True, exist_ok=True)
    log_path = log_dir / f"{name}.log"
    log_file = open(log_path, "a" if append else "w")  # noqa: SIM115 - closed in stop()
    popen = subprocess.Popen(
        [sys.executable, "-m", module, *args],
        env=env,
        stdout=log_file,
        stderr=subprocess.STDOUT,
        stdin=subprocess.DEVNULL,
        preexec_fn=_child_setup,
    )
    return NodeProcess(name, popen, log_path, log_file, (module, tuple(args), dict(env)))


def wait_for(predicate, timeout_s: float, interval_s: float = 0.05) -> bool:
    """Poll ``predicate()`` until it is true or ``timeout_s`` passes."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(interval_s)
    return bool(predicate())
