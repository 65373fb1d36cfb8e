"""rosbag2-compatible MCAP logging without rclpy: schemas, QoS YAML, writer, reader, replay timing.

The ROS adapters (nodes/mcap_recorder_node.py, nodes/mcap_replay_node.py)
only move serialized bytes between DDS and these helpers.
"""

from .msg_definitions import full_message_definition, has_header_first, msg_path
from .qos_yaml import INFINITE_DURATION_NS, QosProfile, dump_qos_profiles, parse_qos_profiles
from .reader import RunReader, TopicSummary
from .writer import McapRunWriter, WriterStats

__all__ = [
    "INFINITE_DURATION_NS",
    "McapRunWriter",
    "QosProfile",
    "RunReader",
    "TopicSummary",
    "WriterStats",
    "dump_qos_profiles",
    "full_message_definition",
    "has_header_first",
    "msg_path",
    "parse_qos_profiles",
]
