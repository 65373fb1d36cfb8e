"""foxglove_bridge: the suite live in Foxglove, over foxglove-sdk's WebSocket server.

Forwards the suite's ROS topics as they are on the wire (raw CDR, never deserialized) on channels
with message encoding ``cdr`` and the full ``ros2msg`` schema text that rosbag2 (and the recorder,
mcap_log.msg_definitions) stores, named by their full ROS names (``/stewart/legs/joint_states``).
It adds a 3D scene in Foxglove's own schemas (stewart_vibration.visualization.scene), published at
``scene_rate_hz`` from the latest ground-truth pose (the 500 Hz streams are only stored, never
processed per message):

- ``<ns>/scene/transforms`` (foxglove.FrameTransforms): base -> platform (ground_truth/platform_pose as it is)
  and base -> leg_1..leg_6 (origin at the base hinge, z along the leg);
- ``<ns>/scene/entities`` (foxglove.SceneUpdate): legs, hinges, base and platform rings, and the
  planned vibration direction (an arrow from the platform origin) while vibration/status says a
  vibration is pending, ramping or running, taken from the planner's vibration/joint_trajectory.

ROS subscriptions follow the Foxglove clients: a topic is subscribed only while a client subscribes
to its channel (ground_truth/platform_pose also while one watches the scene), so with no client the bridge is
idle; the scene's low-rate inputs (vibration/status, vibration/joint_trajectory) stay subscribed, as
a vibration may be sent in one window. Channels are advertised as their topics get a publisher on the
graph; subscriptions take the QoS the publishers offer (rosbag2's rule, as the recorder). Log times:
header.stamp for stamped types (as the recorder's publish time), else the node clock (sim time with
use_sim_time); the server announces the pose's time (Foxglove's "time" capability).

Parameters (read at start): port (8765; 0 = any free port), host (127.0.0.1: this machine only),
scene_rate_hz (30; 0 = no scene), topics ([] = the suite's, those the recorder records),
robot_config ('' = config/robot.yaml). A port in use or a host it cannot listen on: one line, exit 2.
The address is logged as ``Foxglove WebSocket server at ws://HOST:PORT``. /diagnostics: the port and the
count of malformed scene inputs (ignored; the forwarded data is passed on as it is, never read).
"""

from __future__ import annotations

import ipaddress
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import foxglove
from foxglove.channels import FrameTransformsChannel, SceneUpdateChannel
from foxglove.messages import (
    SceneEntityDeletion,
    SceneEntityDeletionType,
    SceneUpdate,
)
from foxglove.websocket import Capability
from rclpy.clock import Clock, ClockType
from rclpy.node import Node

from ..emulation.strut_trajectory import build_trajectory
from ..errors import StewartError
from ..kinematics.robot_config import load_robot
from ..mcap_log.msg_definitions import MessageDefinitionError, full_message_definition, has_header_first
from ..mcap_log.qos_yaml import request_for_offers
from ..messages.cdr import header_stamp_ns
from ..messages.joint_trajectory import decode_joint_trajectory
from ..messages.stamped import poses_from_cdr
from ..messages.status_values import vibration_report_from_cdr
from ..parameters.tables import FOXGLOVE_BRIDGE
from ..robot import VIB_NAMES
from ..visualization import scene as scene_model
from ..visualization.foxglove_schemas import foxglove_entities, foxglove_timestamp, foxglove_transforms
from ..visualization.scene_stream import SceneStream
from .diagnostics import OK, Diagnostics, MalformedInputs
from .mcap_recorder_node import SUITE_TOPICS
from .node_parameters import declare_table
from .ros_graph import message_class, offered_profile, rclpy_profile
from .run_loop import run_node

if TYPE_CHECKING:
    from rclpy.qos import QoSProfile
    from rclpy.subscription import Subscription

SUBSCRIPTION_DEPTH = 100  # history of the forwarding subscriptions (0.2 s of a 500 Hz stream)
DISCOVERY_PERIOD_S = 1.0
RECONCILE_PERIOD_S = 0.2  # subscriptions follow the clients' within this
STATIC_PERIOD_S = 1.0  # the scene's static entities (base, platform) are sent again this often, for new clients


@dataclass
class BridgedTopic:
    """One ROS topic: its Foxglove channel (None: only a scene input) and its live subscription."""

    name: str
    msg_type: type
    qos: QoSProfile
    channel: foxglove.Channel | None = None
    stamped: bool = False  # the type starts with a std_msgs/Header
    scene_input: Callable[[bytes], None] | None = None
    subscription: Subscription | None = None
    forwarding: bool = False


class FoxgloveBridgeNode(Node):
    """Forwards the suite's topics raw to a foxglove-sdk WebSocket server and publishes the 3D scene."""

    def __init__(self, **kwargs):
        super().__init__("foxglove_bridge", **kwargs)
        params = declare_table(self, FOXGLOVE_BRIDGE)
        port, host, rate = params["port"], params["host"], params["scene_rate_hz"]
        names = [t for t in params["topics"] if t]
        self.scene_builder = scene_model.SceneBuilder(load_robot(self.get_parameter("robot_config").value or None))

        self.diagnostics = Diagnostics(self, "foxglove bridge")
        self.malformed = MalformedInputs(self, self.diagnostics)  # the scene's inputs; forwarded data is not read
        self.fox_context = foxglove.Context()
        self._forward = {self.resolve_topic_name(t) for t in (names or SUITE_TOPICS)}
        self._pose_topic = self.resolve_topic_name("ground_truth/platform_pose")
        self._scene_inputs = {
            self._pose_topic: self._on_pose,
            self.resolve_topic_name("vibration/status"): self._on_vibration_status,
            self.resolve_topic_name("vibration/joint_trajectory"): self._on_vibration_window,
        } if rate > 0 else {}
        self._topics: dict[str, BridgedTopic] = {}
        self._pose_data: bytes | None = None
        self._bad_pose: bytes | None = None  # the latest pose found malformed
        self.scene_stream = SceneStream(self.scene_builder, STATIC_PERIOD_S)
        self._clock = self.get_clock()

        self.server = start_websocket_server(host, port, self.fox_context)
        self._transforms = self._entities = None
        if rate > 0:
            ctx = self.fox_context
            self._transforms = FrameTransformsChannel(self.resolve_topic_name("scene/transforms"), context=ctx)
            self._entities = SceneUpdateChannel(self.resolve_topic_name("scene/entities"), context=ctx)
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(DISCOVERY_PERIOD_S, self._discover, clock=steady)
        self.create_timer(RECONCILE_PERIOD_S, self._reconcile, clock=steady)
        if rate > 0:
            self.create_timer(1.0 / rate, self._publish_scene, clock=steady)
        self._discover()
        self.diagnostics.set(OK, "serving", port=self.server.port)
        shown = f"[{host}]" if ":" in host else host
        scope = ("this machine only" if _is_loopback(host)
                 else "reachable from the network: anyone there can read every topic")
        self.get_logger().info(
            f"Foxglove WebSocket server at ws://{shown}:{self.server.port} ({scope}; "
            f"{len(self._forward)} topics as ros2msg/cdr"
            + (f", 3D scene at {rate:g} Hz on {self._transforms.topic()} and {self._entities.topic()})" if rate > 0
               else ", no scene)"))

    # -- topics: discovery, subscriptions that follow the clients ---------------------------------
    def _discover(self) -> None:
        missing = (self._forward | self._scene_inputs.keys()) - self._topics.keys()
        if not missing:
            return
        for topic, types in self.get_topic_names_and_types():
            infos = self.get_publishers_info_by_topic(topic) if topic in missing and len(types) == 1 else None
            if infos:  # a type and a publisher (its QoS offers decide the subscription's)
                self._add_topic(topic, types[0], infos)

    def _add_topic(self, topic: str, type_name: str, infos) -> None:
        try:
            msg_type = message_class(type_name)
            channel = None
            if topic in self._forward:
                schema = foxglove.Schema(name=type_name, encoding="ros2msg",
                                         data=full_message_definition(type_name).encode())
                channel = foxglove.Channel(topic, schema=schema, message_encoding="cdr", context=self.fox_context)
        except (MessageDefinitionError, ImportError, AttributeError, ValueError) as exc:
            self.get_logger().error(f"cannot bridge {topic} ({type_name}): {exc}")
            self._forward.discard(topic)
            self._scene_inputs.pop(topic, None)
            return
        request = request_for_offers([offered_profile(i.qos_profile) for i in infos], SUBSCRIPTION_DEPTH)
        self._topics[topic] = BridgedTopic(topic, msg_type, rclpy_profile(request), channel,
                                           has_header_first(type_name), self._scene_inputs.get(topic))
        self.get_logger().info(f"bridging {topic} [{type_name}] {request.reliability} {request.durability}"
                               + ("" if channel else " (scene input only)"))

    def scene_watched(self) -> bool:
        return self._transforms is not None and (self._transforms.has_sinks() or self._entities.has_sinks())

    def _reconcile(self) -> None:
        """Subscribe a topic while a client watches its channel or the scene it feeds; unsubscribe otherwise.
        The scene's low-rate inputs (vibration status and windows) stay subscribed: a window may be sent once."""
        scene = self.scene_watched()
        for entry in self._topics.values():
            entry.forwarding = entry.channel is not None and entry.channel.has_sinks()
            feeds_scene = entry.scene_input is not None and (scene or entry.name != self._pose_topic)
            wanted = entry.forwarding or feeds_scene
            if wanted and entry.subscription is None:
                entry.subscription = self.create_subscription(
                    entry.msg_type, entry.name, self._callback(entry), entry.qos, raw=True)
            elif not wanted and entry.subscription is not None:
                self.destroy_subscription(entry.subscription)
                entry.subscription = None
                if entry.name == self._pose_topic:
                    self._pose_data = None

    def _callback(self, entry: BridgedTopic):
        """The raw subscription's callback. Log time: header.stamp for stamped types (a few bytes read; the
        node clock costs ~15 us a call, a fifth of the 500 Hz budget), else the node clock (sim time)."""
        clock, channel, scene_input, stamped = self._clock, entry.channel, entry.scene_input, entry.stamped

        def forward(data: bytes) -> None:
            if entry.forwarding:
                stamp = header_stamp_ns(data) if stamped else None
                channel.log(  # type: ignore[union-attr]  # forwarding is set only with a channel
                    data, log_time=stamp if stamp is not None else clock.now().nanoseconds)
            if scene_input is not None:
                scene_input(data)
        return forward

    # -- scene inputs (stored; the scene timer does the work) ---------------------------------------
    def _on_pose(self, data: bytes) -> None:
        self._pose_data = data

    def _on_vibration_status(self, data: bytes) -> None:
        report = self.malformed.read("vibration/status", vibration_report_from_cdr, data)
        if report is None:
            return
        self.scene_stream.on_status(report.state)

    def _on_vibration_window(self, data: bytes) -> None:
        try:
            t = decode_joint_trajectory(data)
            window = build_trajectory(t.names, VIB_NAMES, t.stamp, t.times, t.positions, t.velocities,
                                      t.accelerations)
        except StewartError as exc:
            self.malformed.refuse("vibration/joint_trajectory", exc)
            return
        if len(window.times) < 2:
            return
        self.scene_stream.on_window(window.positions)

    # -- the scene ------------------------------------------------------------------------------
    def _publish_scene(self) -> None:
        data = self._pose_data
        if data is None or not self.scene_watched():
            self.scene_stream.unwatched()
            return
        if data is self._bad_pose:
            return  # judged once (the scene timer would count it at every tick)
        batch = poses_from_cdr([data], "ground_truth/platform_pose", as_quaternion=True)
        if batch.errors:
            self.malformed.refuse("ground_truth/platform_pose", batch.errors[0])
            self._bad_pose = data
            return
        stamp = float(batch.stamps[0])
        frame = self.scene_stream.frame(batch.values[0, :3], batch.values[0, 3:], stamp, time.monotonic())
        now = header_stamp_ns(data) or self._clock.now().nanoseconds  # the pose's time, as its forwarded copy
        self._transforms.log(foxglove_transforms(frame.scene), log_time=now)
        deletions = [SceneEntityDeletion(timestamp=foxglove_timestamp(stamp), type=SceneEntityDeletionType.MatchingId,
                                         id=scene_model.VIBRATION_ENTITY)] if frame.delete_arrow else []
        self._entities.log(SceneUpdate(deletions=deletions, entities=foxglove_entities(frame.scene.stamp,
                                                                                        frame.entities)),
                           log_time=now)
        self.server.broadcast_time(now)

    def shutdown(self) -> None:
        self.server.stop()


def _is_loopback(host: str) -> bool:
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return host == "localhost"


def start_websocket_server(host: str, port: int, context: foxglove.Context):
    """foxglove-sdk's WebSocket server; RuntimeError with one clear line when it cannot listen."""
    try:
        return foxglove.start_server(name="stewart_vibration foxglove_bridge", host=host, port=port,
                                     capabilities=[Capability.Time], context=context)
    except RuntimeError as exc:
        reason = str(exc).removeprefix("FoxgloveError: ")
        hint = ("another program (another bridge?) listens there: stop it or choose -p port:=N"
                if "in use" in reason else "check -p host:= (an address of this machine, e.g. 127.0.0.1)")
        raise RuntimeError(f"Foxglove WebSocket server cannot listen on {host}:{port}: {reason}; {hint}") from None


def main(args=None) -> int:
    """Run the foxglove_bridge node until SIGINT / SIGTERM; returns the exit code (2: it cannot start)."""
    return run_node(FoxgloveBridgeNode, args)


if __name__ == "__main__":
    sys.exit(main())
