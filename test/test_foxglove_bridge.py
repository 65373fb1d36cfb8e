"""foxglove_bridge over a real WebSocket: the hardware emulator and the bridge run as
processes in the suite's namespace; a `websockets` client speaks the Foxglove WebSocket protocol (v1, as
foxglove.sdk.v1) to it as the Foxglove app does, while a raw rclpy subscriber in the test records the same
topics from DDS. The bridge's joint_states must be the very CDR bytes DDS carried, and its scene's platform
frame the ground-truth pose of the same stamp. A port in use: one error line, exit code 2."""

from __future__ import annotations

import asyncio
import json
import socket
import struct
import threading

import numpy as np
import pytest
import websockets
from geometry_msgs.msg import PoseStamped
from ros_client import RosTestClient
from sensor_msgs.msg import JointState

from stewart_vibration.mcap_log.msg_definitions import full_message_definition
from stewart_vibration.messages.joint_states import JointStateDecoder
from stewart_vibration.messages.stamped_doubles import decode_pose_stamped
from stewart_vibration.runtime.processes import ros_environment, start_python_module, wait_for

pytestmark = pytest.mark.integration
NS = "/stewart"
ARGS = ["--ros-args", "-r", f"__ns:={NS}", "-p", "use_sim_time:=true"]
SUBPROTOCOL = "foxglove.sdk.v1"  # foxglove-sdk's name for Foxglove WebSocket protocol v1
# what the emulator alone publishes (suite topics), and the bridge's scene
EMULATOR_TOPICS = {
    f"{NS}/legs/joint_states": "sensor_msgs/msg/JointState",
    f"{NS}/ground_truth/platform_pose": "geometry_msgs/msg/PoseStamped",
    f"{NS}/vibration/status": "stewart_vibration_interfaces/msg/VibrationUnitsStatus",
    f"{NS}/robot_markers": "visualization_msgs/msg/MarkerArray",
    "/clock": "rosgraph_msgs/msg/Clock",
    "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
    "/rosout": "rcl_interfaces/msg/Log",
}
SCENE = {f"{NS}/scene/transforms": "foxglove.FrameTransforms", f"{NS}/scene/entities": "foxglove.SceneUpdate"}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# -- protobuf wire format (the Foxglove schemas), written here: enough for FrameTransforms / SceneUpdate --
def protobuf_fields(buf: bytes) -> dict[int, list]:
    """field number -> values (varints as int, fixed64 as float, length-delimited as bytes)."""
    fields, i = {}, 0

    def varint():
        nonlocal i
        value = shift = 0
        while True:
            b = buf[i]
            i += 1
            value |= (b & 0x7F) << shift
            shift += 7
            if b < 0x80:
                return value

    while i < len(buf):
        key = varint()
        number, wire = key >> 3, key & 7
        if wire == 0:
            value = varint()
        elif wire == 1:
            (value,), i = struct.unpack_from("<d", buf, i), i + 8
        elif wire == 2:
            n = varint()
            value, i = buf[i:i + n], i + n
        elif wire == 5:
            value, i = buf[i:i + 4], i + 4
        else:
            raise ValueError(f"wire type {wire}")
        fields.setdefault(number, []).append(value)
    return fields


def one(fields, number, default):
    return fields.get(number, [default])[0]


def decode_vector(buf: bytes, names: str) -> np.ndarray:
    f = protobuf_fields(buf)
    return np.array([one(f, k + 1, 0.0) for k in range(len(names))])


def decode_transforms(buf: bytes) -> dict[str, tuple]:
    """FrameTransforms -> child -> (stamp ns, parent, translation (3,), rotation (4,) [x, y, z, w])."""
    out = {}
    for raw in protobuf_fields(buf).get(1, []):
        t = protobuf_fields(raw)
        stamp = protobuf_fields(one(t, 1, b""))
        out[one(t, 3, b"").decode()] = (one(stamp, 1, 0) * 1_000_000_000 + one(stamp, 2, 0), one(t, 2, b"").decode(),
                                        decode_vector(one(t, 4, b""), "xyz"), decode_vector(one(t, 5, b""), "xyzw"))
    return out


def decode_entity_ids(buf: bytes) -> dict[str, str]:
    """SceneUpdate -> entity id -> frame id."""
    return {one(e, 3, b"").decode(): one(e, 2, b"").decode()
            for e in (protobuf_fields(raw) for raw in protobuf_fields(buf).get(2, []))}


def cdr_stamp_ns(data: bytes) -> int:
    sec, nanosec = struct.unpack_from("<iI", data, 4)  # after the 4-byte encapsulation header
    return sec * 1_000_000_000 + nanosec


async def foxglove_session(port: int, wanted: set[str], listen_s: float) -> tuple[dict, dict, dict]:
    """(serverInfo, topic -> advertised channel, topic -> [(log time, payload)]) of one client session."""
    async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=[SUBPROTOCOL], max_size=None) as ws:
        assert ws.subprotocol == SUBPROTOCOL
        info = json.loads(await asyncio.wait_for(ws.recv(), 10))
        channels = {}
        loop = asyncio.get_running_loop()
        deadline = loop.time() + 30
        while not wanted <= channels.keys() and loop.time() < deadline:
            msg = await asyncio.wait_for(ws.recv(), max(deadline - loop.time(), 0.1))
            if isinstance(msg, str) and json.loads(msg)["op"] == "advertise":
                channels.update({c["topic"]: c for c in json.loads(msg)["channels"]})
        subscribe = [t for t in (f"{NS}/legs/joint_states", *SCENE) if t in channels]
        by_id = {i: t for i, t in enumerate(subscribe, start=10)}
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
            {"id": i, "channelId": channels[t]["id"]} for i, t in by_id.items()]}))
        received = {t: [] for t in subscribe}
        deadline = loop.time() + listen_s
        while loop.time() < deadline:
            try:
                msg = await asyncio.wait_for(ws.recv(), 1.0)
            except TimeoutError:
                continue
            if isinstance(msg, bytes) and msg[0] == 1:  # messageData: op, subscription id, log time, payload
                sub_id, log_time = struct.unpack_from("<IQ", msg, 1)
                received[by_id[sub_id]].append((log_time, msg[13:]))
        return info, channels, received


@pytest.fixture
def emulator_and_bridge(ros_domain, tmp_path):
    env = ros_environment(ros_domain)
    port = free_port()
    procs = [start_python_module("emulator", "stewart_vibration.nodes.hardware_emulator_node",
                                 ARGS[:3] + ["-p", "real_time_factor:=1"], env, tmp_path),
             start_python_module("bridge", "stewart_vibration.nodes.foxglove_bridge_node",
                                 ARGS + ["-p", f"port:={port}"], env, tmp_path)]
    try:
        yield port, procs
    finally:
        for proc in procs:
            proc.stop()


def logs(procs) -> str:
    return "\n".join(f"--- {p.name}\n{p.log_text()[-3000:]}" for p in procs)


def test_bridge_forwards_raw_cdr_and_publishes_the_scene(emulator_and_bridge):
    port, procs = emulator_and_bridge
    assert wait_for(lambda: f"ws://127.0.0.1:{port}" in procs[1].log_text(), 30), logs(procs)
    client = RosTestClient()
    dds = {"states": {}, "poses": {}}
    client.node.create_subscription(
        JointState, f"{NS}/legs/joint_states", lambda d: dds["states"].setdefault(cdr_stamp_ns(d), d), 1000, raw=True)
    client.node.create_subscription(
        PoseStamped, f"{NS}/ground_truth/platform_pose", lambda d: dds["poses"].setdefault(cdr_stamp_ns(d), d), 1000,
        raw=True)
    stop = threading.Event()
    spinner = threading.Thread(target=lambda: [client.spin_for(0.1) for _ in iter(stop.is_set, True)], daemon=True)
    spinner.start()
    try:
        info, channels, received = asyncio.run(foxglove_session(port, set(EMULATOR_TOPICS) | set(SCENE), 4.0))
    finally:
        stop.set()
        spinner.join(5)
        client.close()

    assert info["op"] == "serverInfo" and "time" in info["capabilities"], info
    for topic, type_name in EMULATOR_TOPICS.items():  # every suite topic on the graph, as rosbag2 stores it
        assert topic in channels, (topic, sorted(channels), logs(procs))
        c = channels[topic]
        assert (c["encoding"], c["schemaName"], c["schemaEncoding"]) == ("cdr", type_name, "ros2msg")
        assert c["schema"] == full_message_definition(type_name)
    for topic, schema in SCENE.items():
        assert (channels[topic]["encoding"], channels[topic]["schemaName"]) == ("protobuf", schema)

    # joint_states: byte for byte what DDS carried for the same stamp
    states = received[f"{NS}/legs/joint_states"]
    assert len(states) > 250, (len(states), logs(procs))  # ~1,800 in ~3.8 s at 500 Hz; fewer on a busy machine
    matched = [(payload, dds["states"][cdr_stamp_ns(payload)]) for _, payload in states
               if cdr_stamp_ns(payload) in dds["states"]]
    assert len(matched) > 0.9 * len(states), (len(matched), len(states))
    assert all(a == b for a, b in matched)
    decoded = JointStateDecoder().decode(matched[-1][0])
    assert list(decoded.names)[:6] == [f"leg_{i}" for i in range(1, 7)]

    # the scene: frames for the platform and every leg, the platform frame = the ground-truth pose
    frames = [decode_transforms(p) for _, p in received[f"{NS}/scene/transforms"]]
    assert len(frames) >= 30, len(frames)  # ~100: 30 Hz for ~3.5 s
    checked = 0
    for tf in frames:
        assert set(tf) == {"platform", *(f"leg_{i}" for i in range(1, 7))}
        assert {parent for _, parent, _, _ in tf.values()} == {"base"}
        stamp, _, translation, rotation = tf["platform"]
        if stamp in dds["poses"]:
            _, frame, position, quaternion = decode_pose_stamped(dds["poses"][stamp])
            assert frame == "base"
            np.testing.assert_allclose(translation, position, rtol=0, atol=1e-9)
            np.testing.assert_allclose(rotation, quaternion, rtol=0, atol=1e-9)
            checked += 1
    assert checked > 0.9 * len(frames), (checked, len(frames))
    # entities: the legs in every update, the static base and platform (rings, hinges) again every second
    updates = [decode_entity_ids(p) for _, p in received[f"{NS}/scene/entities"]]
    legs = {f"leg_{i}": f"leg_{i}" for i in range(1, 7)}
    assert all(u.items() >= legs.items() for u in updates)
    assert {k: v for u in updates for k, v in u.items()} == {"base": "base", "platform": "platform", **legs}
    assert sum("base" in u and "platform" in u for u in updates) >= 2, len(updates)  # ~3.5 s of updates


def test_port_in_use_gives_one_line_and_exit_2(ros_domain, tmp_path):
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        proc = start_python_module("bridge", "stewart_vibration.nodes.foxglove_bridge_node",
                                   ARGS + ["-p", f"port:={port}"], ros_environment(ros_domain), tmp_path)
        try:
            proc.popen.wait(timeout=60)
        finally:
            proc.stop()
    text = proc.log_text()
    assert proc.popen.returncode == 2, text
    assert "Traceback" not in text, text
    lines = [line for line in text.splitlines() if line.strip()]
    assert len(lines) == 1, text
    assert f"cannot listen on 127.0.0.1:{port}" in lines[0] and "in use" in lines[0], text
