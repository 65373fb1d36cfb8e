"""DDS stays on this machine (docs/security.md): with the bring-up's default environment
(config/fastdds_localhost.xml) real nodes talk to each other and to a client, and every socket they
own is bound to a loopback address; with STEWART_DDS_PROFILE=multihost the same check sees sockets on
0.0.0.0 (so it can tell the difference). Sockets are read from /proc: the inodes of /proc/<pid>/fd
looked up in /proc/<pid>/net/{udp,udp6,tcp,tcp6}; shared-memory segments from /proc/<pid>/maps (the loopback
profile has none, the multihost one has)."""

from __future__ import annotations

import ipaddress
import json
import os
import socket
import subprocess
import sys
import types
from pathlib import Path

import pytest
from geometry_msgs.msg import PoseStamped
from ros_client import RosTestClient
from sensor_msgs.msg import JointState

from stewart_vibration.runtime.processes import (
    DDS_PROFILE_ENV,
    apply_environment,
    dds_environment,
    loopback_profile_path,
    ros_environment,
    start_python_module,
    wait_for,
)

pytestmark = pytest.mark.integration
ROOT = Path(__file__).resolve().parents[1] / "stewart_vibration"  # the ament_python package directory
SIM = ["--ros-args", "-p", "use_sim_time:=true"]
EMULATOR = "stewart_vibration.nodes.hardware_emulator_node"
KINEMATICS = "stewart_vibration.nodes.kinematics_node"


def _address(hex_address: str, v6: bool) -> tuple[str, int]:
    """'0100007F:1CE8' (little-endian words, as /proc/net shows them) -> ('127.0.0.1', 7400)."""
    host, port = hex_address.split(":")
    raw = bytes.fromhex(host)
    if v6:
        raw = b"".join(raw[i:i + 4][::-1] for i in range(0, 16, 4))
        return socket.inet_ntop(socket.AF_INET6, raw), int(port, 16)
    return socket.inet_ntop(socket.AF_INET, raw[::-1]), int(port, 16)


def _pids(pid: int) -> set[int]:
    """pid and its descendants."""
    found, todo = set(), [pid]
    while todo:
        p = todo.pop()
        found.add(p)
        for task in Path(f"/proc/{p}/task").glob("*"):
            try:
                todo += [int(c) for c in (task / "children").read_text().split()]
            except OSError:
                pass
    return found


def inet_sockets(pid: int) -> list[tuple[str, str, int]]:
    """(protocol, local address, port) of every UDP/TCP socket, IPv4 and IPv6, owned by pid or a child."""
    inodes = set()
    for p in _pids(pid):
        for fd in Path(f"/proc/{p}/fd").glob("*"):
            try:
                target = os.readlink(fd)
            except OSError:
                continue
            if target.startswith("socket:["):
                inodes.add(int(target[8:-1]))
    found = []
    for proto in ("udp", "udp6", "tcp", "tcp6"):
        try:
            lines = Path(f"/proc/{pid}/net/{proto}").read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            fields = line.split()
            if int(fields[9]) in inodes:
                found.append((proto, *_address(fields[1], proto.endswith("6"))))
    return found


def shared_memory_segments(pid: int) -> set[str]:
    """The Fast DDS shared-memory files (/dev/shm/fastrtps_* or fastdds_*: ports and data segments) that pid
    or a child has mapped."""
    found = set()
    for p in _pids(pid):
        try:
            maps = Path(f"/proc/{p}/maps").read_text().splitlines()
        except OSError:
            continue
        found |= {line.split()[-1] for line in maps
                  if "/dev/shm/fastrtps_" in line or "/dev/shm/fastdds_" in line}
    return found


def is_loopback(address: str) -> bool:
    ip = ipaddress.ip_address(address)
    if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
        ip = ip.ipv4_mapped
    return ip.is_loopback


def use_in_this_process(monkeypatch, changes: dict) -> None:
    """The DDS variables for this process too (the RosTestClient), before its first participant."""
    for key, value in changes.items():
        if value is None:
            monkeypatch.delenv(key, raising=False)
        else:
            monkeypatch.setenv(key, value)


def test_suite_processes_talk_and_bind_only_loopback(ros_domain, tmp_path, monkeypatch):
    monkeypatch.delenv(DDS_PROFILE_ENV, raising=False)
    env = ros_environment(ros_domain)
    profile = str(loopback_profile_path())
    assert env["FASTRTPS_DEFAULT_PROFILES_FILE"] == profile == env["FASTDDS_DEFAULT_PROFILES_FILE"]
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SYSTEM_DEFAULT"
    use_in_this_process(monkeypatch, dds_environment())
    procs = [
        start_python_module("emulator", EMULATOR, ["--ros-args", "-p", "real_time_factor:=1"], env, tmp_path),
        start_python_module("kinematics", KINEMATICS, SIM, env, tmp_path),
    ]
    client = RosTestClient()
    try:
        states = client.subscribe("legs/joint_states", JointState)
        estimates = client.subscribe("platform/pose_estimate", PoseStamped)  # emulator -> kinematics -> client
        logs = lambda: "\n".join(f"--- {p.name}\n{p.log_text()[-2000:]}" for p in procs)  # noqa: E731
        assert client.spin_until(lambda: states and estimates, 40.0), logs()
        assert all(p.alive() for p in procs), logs()
        found = {p.name: inet_sockets(p.popen.pid) for p in procs}
        print("sockets:", found)
        for name, sockets in found.items():
            assert sockets, f"{name}: no UDP/TCP socket found, so the check would prove nothing"
            outside = [s for s in sockets if not is_loopback(s[1])]
            assert not outside, f"{name} binds non-loopback addresses: {outside} (all: {sockets})"
        # no shared-memory transport: a stalled or killed process would leave ports behind in /dev/shm
        shared = {p.name: shared_memory_segments(p.popen.pid) for p in procs}
        assert not any(shared.values()), f"nodes map Fast DDS shared memory: {shared}"
    finally:
        client.close()
        for proc in procs:
            proc.stop()


def test_multihost_setting_binds_all_interfaces(ros_domain, tmp_path, monkeypatch):
    """The same check on STEWART_DDS_PROFILE=multihost (Fast DDS defaults) finds 0.0.0.0 and shared memory."""
    monkeypatch.setenv(DDS_PROFILE_ENV, "multihost")
    env = ros_environment(ros_domain)
    assert "FASTRTPS_DEFAULT_PROFILES_FILE" not in env and env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SUBNET"
    proc = start_python_module("emulator", EMULATOR, ["--ros-args", "-p", "real_time_factor:=1"], env, tmp_path)
    try:
        anywhere = lambda: [s for s in inet_sockets(proc.popen.pid) if s[1] in ("0.0.0.0", "::")]  # noqa: E731
        assert wait_for(anywhere, 30.0), f"{inet_sockets(proc.popen.pid)}\n{proc.log_text()[-2000:]}"
        print("multihost sockets:", inet_sockets(proc.popen.pid))
        # Fast DDS's defaults include shared memory, so the loopback test's check of it can fail
        assert wait_for(lambda: shared_memory_segments(proc.popen.pid), 10.0)
    finally:
        proc.stop()


def test_profile_choice_and_its_errors(tmp_path):
    own = tmp_path / "own.xml"
    own.write_text((ROOT / "config" / "fastdds_localhost.xml").read_text())
    assert loopback_profile_path() == (ROOT / "config" / "fastdds_localhost.xml").resolve()
    assert dds_environment("loopback") == dds_environment(None) == dds_environment("")
    assert dds_environment(str(own))["FASTRTPS_DEFAULT_PROFILES_FILE"] == str(own.resolve())
    base = {"ROS_LOCALHOST_ONLY": "1", DDS_PROFILE_ENV: "loopback"}
    assert "ROS_LOCALHOST_ONLY" not in ros_environment(3, base)  # its 1 would re-add rmw's 0.0.0.0 transport
    with pytest.raises(ValueError, match="multihost"):
        dds_environment("multi-host")  # a typo is refused, never all interfaces
    with pytest.raises(FileNotFoundError, match="fastdds_localhost.xml"):
        loopback_profile_path(tmp_path)


def test_reliable_writers_repair_a_lost_sample_within_50_ms():
    """The profile's default DataWriter sends a heartbeat every 50 ms: a reader that missed a sample of a
    reliable stream gets the later ones only once a heartbeat has started the repair, and with Fast DDS's 3 s
    default a newly matched reader of an estimate stream saw p99 0.6-1.8 s (benchmarks/suite_cpu.py; the file is
    loaded by the nodes of test_suite_processes_talk_and_bind_only_loopback, whose sockets show it is in force)."""
    import xml.etree.ElementTree as ET

    ns = {"dds": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}
    root = ET.parse(ROOT / "config" / "fastdds_localhost.xml").getroot()
    writers = [w for w in root.iterfind("dds:profiles/dds:data_writer", ns) if w.get("is_default_profile") == "true"]
    assert len(writers) == 1
    period = writers[0].find("dds:times/dds:heartbeatPeriod", ns)
    seconds = int(period.find("dds:sec", ns).text) + int(period.find("dds:nanosec", ns).text) * 1e-9
    assert seconds == pytest.approx(0.05)


# A server whose answers can never reach a client (its response reader asks for TRANSIENT_LOCAL, the
# server's response writer offers VOLATILE): the server waits for the match before dropping each answer,
# so the gap between two requests' callbacks is its response writer's max_blocking_time.
_UNREACHABLE_CLIENT = """
import json, time
import rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile
from std_srvs.srv import Trigger

rclpy.init()
node = rclpy.create_node("answer_wait_probe")
entered = []
def answer(request, response):
    entered.append(time.monotonic())
    response.success = True
    return response
node.create_service(Trigger, "probe", answer)
good = node.create_client(Trigger, "probe")
strict = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL)
deaf = node.create_client(Trigger, "probe", qos_profile=strict)
assert good.wait_for_service(timeout_sec=20)
sent = time.monotonic()
future = good.call_async(Trigger.Request())
rclpy.spin_until_future_complete(node, future, timeout_sec=10)
answered = time.monotonic() - sent if future.done() and future.result().success else None
time.sleep(0.5)  # the deaf client's request writer is matched by now (same participant)
deaf.call_async(Trigger.Request())
deaf.call_async(Trigger.Request())
end = time.monotonic() + 20
while len(entered) < 3 and time.monotonic() < end:
    rclpy.spin_once(node, timeout_sec=0.05)
print(json.dumps({"answered_s": answered, "wait_s": entered[2] - entered[1] if len(entered) == 3 else None}))
"""


def _answer_waits(env: dict) -> dict:
    result = subprocess.run([sys.executable, "-c", _UNREACHABLE_CLIENT], env=env, capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr[-3000:]
    return json.loads(result.stdout.strip().splitlines()[-1])


def test_services_wait_a_second_for_their_client_before_dropping_an_answer(ros_domain):
    """A service's answer goes out only once discovery has matched the client's response reader, which can
    come after its request; Fast DDS waits the response writer's max_blocking_time (100 ms) and then drops
    the answer, and the client (ros2cli's send_goal, a UI) waits forever. The profile gives service response
    writers 1 s: measured on a server that can never reach its client, against Fast DDS's own defaults."""
    profiled = _answer_waits(ros_environment(ros_domain))
    defaults = _answer_waits(apply_environment(ros_environment(ros_domain), {
        **dict.fromkeys(("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")),
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}))
    print("profile:", profiled, "Fast DDS defaults:", defaults)
    assert profiled["answered_s"] is not None and profiled["answered_s"] < 1.0  # a reachable client: at once
    assert 0.95 <= profiled["wait_s"] < 2.0
    assert defaults["wait_s"] < 0.5


def _launch_actions(monkeypatch, share_dir: Path):
    """generate_launch_description() of the launch file with launch/launch_ros (not on PyPI) stubbed."""

    def record(kind):
        return lambda *args, **kwargs: (kind, args, kwargs)

    stubs = {
        "launch": types.SimpleNamespace(LaunchDescription=lambda actions: actions),
        "launch.actions": types.SimpleNamespace(
            DeclareLaunchArgument=record("arg"), SetEnvironmentVariable=record("set"),
            UnsetEnvironmentVariable=record("unset"), EmitEvent=record("emit"),
            RegisterEventHandler=record("handler")),
        "launch.events": types.SimpleNamespace(matches_action=record("matches")),
        "launch.conditions": types.SimpleNamespace(IfCondition=record("if")),
        "launch.substitutions": types.SimpleNamespace(LaunchConfiguration=record("config")),
        "launch_ros": types.SimpleNamespace(),
        "launch_ros.actions": types.SimpleNamespace(Node=record("node"), LifecycleNode=record("lifecycle_node")),
        "launch_ros.event_handlers": types.SimpleNamespace(OnStateTransition=record("on_transition")),
        "launch_ros.events": types.SimpleNamespace(),
        "launch_ros.events.lifecycle": types.SimpleNamespace(ChangeState=record("change_state")),
        "launch_ros.parameter_descriptions": types.SimpleNamespace(ParameterValue=record("parameter_value")),
        "ament_index_python.packages": types.SimpleNamespace(get_package_share_directory=lambda _: str(share_dir)),
    }
    for name, module in stubs.items():
        monkeypatch.setitem(sys.modules, name, module)
    code = compile((ROOT / "launch" / "stewart_vibration.launch.py").read_text(), "launch.py", "exec")
    scope: dict = {"__name__": "launch_file"}
    exec(code, scope)  # noqa: S102 - the project's own launch file
    return scope["generate_launch_description"]()


def test_launch_file_sets_the_profile_from_the_share_dir_before_the_nodes(monkeypatch):
    monkeypatch.delenv(DDS_PROFILE_ENV, raising=False)
    actions = _launch_actions(monkeypatch, ROOT)  # share dir stand-in: holds config/
    kinds = [a[0] for a in actions]
    env = {a[1][0]: a[1][1] for a in actions if a[0] == "set"}
    assert env["FASTRTPS_DEFAULT_PROFILES_FILE"] == str((ROOT / "config" / "fastdds_localhost.xml").resolve())
    assert env["FASTDDS_DEFAULT_PROFILES_FILE"] == env["FASTRTPS_DEFAULT_PROFILES_FILE"]
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SYSTEM_DEFAULT"
    first_node = min(i for i, k in enumerate(kinds) if k in ("node", "lifecycle_node"))
    assert max(i for i, k in enumerate(kinds) if k in ("set", "unset")) < first_node
    monkeypatch.setenv(DDS_PROFILE_ENV, "multihost")
    actions = _launch_actions(monkeypatch, ROOT)
    assert {a[1][0] for a in actions if a[0] == "unset"} >= {"FASTRTPS_DEFAULT_PROFILES_FILE",
                                                            "FASTDDS_DEFAULT_PROFILES_FILE"}
    assert ("set", ("ROS_AUTOMATIC_DISCOVERY_RANGE", "SUBNET"), {}) in actions
