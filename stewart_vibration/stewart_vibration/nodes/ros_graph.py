"""What the ROS graph offers, as the MCAP recorder, the replay and the Foxglove bridge need it: QoS
profiles converted to and from the pure ``mcap_log.qos_yaml.QosProfile``, and message classes by type name."""

from __future__ import annotations

import importlib

from rclpy.duration import Duration
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    LivelinessPolicy,
    QoSProfile,
    ReliabilityPolicy,
)

from ..mcap_log.qos_yaml import QosProfile


def offered_profile(qos: QoSProfile) -> QosProfile:
    """rclpy QoSProfile (as discovered on the graph) -> pure QosProfile."""
    return QosProfile(
        history=qos.history.name.lower(),
        depth=int(qos.depth),
        reliability=qos.reliability.name.lower(),
        durability=qos.durability.name.lower(),
        deadline_ns=int(qos.deadline.nanoseconds),
        lifespan_ns=int(qos.lifespan.nanoseconds),
        liveliness=qos.liveliness.name.lower(),
        liveliness_lease_duration_ns=int(qos.liveliness_lease_duration.nanoseconds),
        avoid_ros_namespace_conventions=bool(qos.avoid_ros_namespace_conventions),
    )


def rclpy_profile(p: QosProfile) -> QoSProfile:
    """Pure QosProfile -> rclpy QoSProfile (history, depth, reliability, durability)."""
    history = HistoryPolicy[p.history.upper()]
    if history not in (HistoryPolicy.KEEP_LAST, HistoryPolicy.KEEP_ALL):
        history = HistoryPolicy.KEEP_LAST
    qos = QoSProfile(
        history=history,
        depth=max(1, int(p.depth)),
        reliability=ReliabilityPolicy[p.reliability.upper()],
        durability=DurabilityPolicy[p.durability.upper()],
    )
    if p.liveliness in ("automatic", "manual_by_topic"):
        qos.liveliness = LivelinessPolicy[p.liveliness.upper()]
    if 0 < p.deadline_ns < 2**63 - 1:
        qos.deadline = Duration(nanoseconds=p.deadline_ns)
    return qos


def message_class(type_name: str):
    """``pkg/msg/Type`` -> the generated Python message class."""
    pkg, ns, name = type_name.split("/")
    return getattr(importlib.import_module(f"{pkg}.{ns}"), name)
