"""Listen to one topic as a subscriber that loses nothing (for ``stewart-vibration topic-rate``): the publishers'
reliability (rosbag2's rule) and a deep queue; the arrival times and, for stamped messages, the header stamps."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from ..mcap_log.msg_definitions import has_header_first
from ..mcap_log.qos_yaml import QosProfile, request_for_offers
from ..messages.cdr import header_stamp_ns
from .ros_graph import message_class, offered_profile, rclpy_profile


@dataclass
class Heard:
    """What one listen took: the topic's type, the QoS it listened with, arrival times (monotonic s) and stamps
    (s; NaN without one; empty for unstamped types)."""

    type_name: str
    qos: QosProfile
    stamped: bool
    arrivals: list[float] = field(default_factory=list)
    stamps: list[float] = field(default_factory=list)


def listen(topic: str, seconds: float, wait_s: float, depth: int) -> Heard | None:
    """Listen to ``topic`` for ``seconds`` of wall time once a publisher is seen within ``wait_s``; None if none
    is. Runs rclpy in this process (init and shutdown)."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(f"topic_rate_{int(time.time() * 1000) % 100000}")
    try:
        deadline = time.monotonic() + wait_s
        publishers = node.get_publishers_info_by_topic(topic)
        while not publishers and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.1)
            publishers = node.get_publishers_info_by_topic(topic)
        if not publishers:
            return None
        type_name = publishers[0].topic_type
        heard = Heard(type_name, request_for_offers([offered_profile(p.qos_profile) for p in publishers], depth),
                      has_header_first(type_name))

        def on_message(data: bytes) -> None:
            heard.arrivals.append(time.monotonic())
            if heard.stamped:
                ns = header_stamp_ns(data)
                heard.stamps.append(float("nan") if ns is None else ns * 1e-9)

        node.create_subscription(message_class(type_name), topic, on_message, rclpy_profile(heard.qos), raw=True)
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.05)
        return heard
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
