"""rosbag2 bag metadata (version 9, Jazzy): the ``metadata.yaml`` of a bag directory.

rosbag2 (rosbag2_storage/yaml.hpp, metadata_io.cpp) writes the BagMetadata
with yaml-cpp under the key ``rosbag2_bagfile_information``; the MCAP storage
plugin embeds the same mapping (without that key) as the ``serialized_metadata``
of a ``rosbag2`` metadata record. Version 9 stores each topic's
``offered_qos_profiles`` as a YAML sequence (policies as rmw strings,
durations as ``{sec, nsec}``); the MCAP channel metadata keeps them as text.
``dump_bag_metadata`` writes yaml-cpp's block layout (2-space indent,
sequences indented under their key, ``""`` for empty strings, ``~`` for an
empty custom_data map).

A bag directory holds ``metadata.yaml`` plus the files it lists in
``relative_file_paths``; readers (``ros2 bag``, rosbags) ignore anything else
in the folder (logs, reports, older recordings).
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from .qos_yaml import QosProfile, parse_qos_profiles

METADATA_FILE = "metadata.yaml"
ROOT_KEY = "rosbag2_bagfile_information"
VERSION = 9
ROS_DISTRO = "jazzy"
_NS = 1_000_000_000


@dataclass
class TopicCount:
    """One topic of a bag: ``qos_yaml`` is the channel's offered_qos_profiles text."""

    name: str
    type_name: str
    qos_yaml: str = ""
    type_hash: str = ""
    message_count: int = 0


@dataclass
class BagFile:
    """One storage file of a bag: its name (relative to the bag directory), times in ns, topics."""

    path: str
    start_ns: int = 0
    end_ns: int = 0
    topics: list[TopicCount] = field(default_factory=list)

    @property
    def message_count(self) -> int:
        """Messages in this file, over all its topics."""
        return sum(t.message_count for t in self.topics)

    @property
    def duration_ns(self) -> int:
        """Log time from the first to the last message (ns); 0 without messages."""
        return max(0, self.end_ns - self.start_ns) if self.message_count else 0


def bag_metadata(files: list[BagFile], custom_data: dict[str, str] | None = None) -> dict:
    """The BagMetadata mapping (without the root key) of a bag made of ``files``, in order."""
    with_messages = [f for f in files if f.message_count]
    start = min((f.start_ns for f in with_messages), default=0)
    end = max((f.end_ns for f in with_messages), default=0)
    topics: dict[str, TopicCount] = {}
    for f in files:
        for t in f.topics:
            known = topics.get(t.name)
            if known is None:
                topics[t.name] = TopicCount(t.name, t.type_name, t.qos_yaml, t.type_hash, t.message_count)
            else:
                known.message_count += t.message_count
    return {
        "version": VERSION,
        "storage_identifier": "mcap",
        "duration": {"nanoseconds": max(0, end - start)},
        "starting_time": {"nanoseconds_since_epoch": start},
        "message_count": sum(f.message_count for f in files),
        "topics_with_message_count": [
            {
                "topic_metadata": {
                    "name": t.name,
                    "type": t.type_name,
                    "serialization_format": "cdr",
                    "offered_qos_profiles": [_qos_dict(p) for p in parse_qos_profiles(t.qos_yaml)],
                    "type_description_hash": t.type_hash,
                },
                "message_count": t.message_count,
            }
            for t in topics.values()
        ],
        "compression_format": "",
        "compression_mode": "",
        "relative_file_paths": [f.path for f in files],
        "files": [
            {
                "path": f.path,
                "starting_time": {"nanoseconds_since_epoch": f.start_ns if f.message_count else 0},
                "duration": {"nanoseconds": f.duration_ns},
                "message_count": f.message_count,
            }
            for f in files
        ],
        "custom_data": dict(custom_data or {}),
        "ros_distro": ROS_DISTRO,
    }


def _qos_dict(p: QosProfile) -> dict:
    def duration(ns: int) -> dict:
        sec, nsec = divmod(int(ns), _NS)
        return {"sec": sec, "nsec": nsec}

    return {
        "history": p.history,
        "depth": int(p.depth),
        "reliability": p.reliability,
        "durability": p.durability,
        "deadline": duration(p.deadline_ns),
        "lifespan": duration(p.lifespan_ns),
        "liveliness": p.liveliness,
        "liveliness_lease_duration": duration(p.liveliness_lease_duration_ns),
        "avoid_ros_namespace_conventions": bool(p.avoid_ros_namespace_conventions),
    }


# -- yaml-cpp style emitter ------------------------------------------------------------
_PLAIN = re.compile(r"^[A-Za-z_/][A-Za-z0-9_./\-]*$")
_RESERVED = frozenset(
    "~ null Null NULL true True TRUE false False FALSE yes Yes YES no No NO on On ON off Off OFF y Y n N".split()
)


def _scalar(value) -> str:
    if value is None:
        return "~"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    text = str(value)
    if _PLAIN.match(text) and text not in _RESERVED:
        return text
    return json.dumps(text)  # yaml-cpp double-quotes what a plain scalar cannot carry


def _block(value, indent: int) -> list[str]:
    """Lines of a non-empty mapping or sequence in yaml-cpp's block style at ``indent``."""
    pad = " " * indent
    lines: list[str] = []
    if isinstance(value, dict):
        for k, v in value.items():
            if isinstance(v, (dict, list)) and v:
                lines.append(f"{pad}{k}:")
                lines += _block(v, indent + 2)
            elif isinstance(v, list):
                lines.append(f"{pad}{k}: []")
            elif isinstance(v, dict):
                lines.append(f"{pad}{k}: ~")  # an empty std::map encodes as a null node
            else:
                lines.append(f"{pad}{k}: {_scalar(v)}")
        return lines
    for item in value:
        if isinstance(item, dict) and item:
            sub = _block(item, indent + 2)
            sub[0] = f"{pad}- {sub[0].lstrip()}"
            lines += sub
        else:
            lines.append(f"{pad}- {_scalar(item)}")
    return lines


def dump_bag_metadata(meta: dict, root: bool = True) -> str:
    """YAML text of a BagMetadata mapping as yaml-cpp writes it (``root``: under rosbag2_bagfile_information)."""
    if root:
        return "\n".join([f"{ROOT_KEY}:", *_block(meta, 2)])
    return "\n".join(_block(meta, 0))


def write_metadata_yaml(directory: str | Path, meta: dict) -> Path:
    """Write ``directory/metadata.yaml`` atomically (temporary file, then rename)."""
    path = Path(directory) / METADATA_FILE
    tmp = path.with_name(f".{METADATA_FILE}.tmp{os.getpid()}")
    tmp.write_text(dump_bag_metadata(meta) + "\n")
    os.replace(tmp, path)
    return path


def read_metadata_yaml(directory: str | Path) -> dict:
    """The BagMetadata mapping of a bag directory (KeyError/yaml errors for a malformed file)."""
    data = yaml.safe_load((Path(directory) / METADATA_FILE).read_text())
    return data[ROOT_KEY]


def remove_metadata_yaml(directory: str | Path) -> bool:
    """Delete ``directory/metadata.yaml`` if present; True if one was removed."""
    try:
        (Path(directory) / METADATA_FILE).unlink()
    except FileNotFoundError:
        return False
    return True
