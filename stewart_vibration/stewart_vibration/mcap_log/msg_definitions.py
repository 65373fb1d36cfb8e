"""Full ``ros2msg`` message definitions in rosbag2's layout, built from installed .msg files.

rosbag2 (rosbag2_cpp LocalMessageDefinitionSource) stores, for a type
``pkg/msg/Type``, the text of ``<share>/pkg/msg/Type.msg`` as it is on disk,
then for every dependency not yet emitted (depth first, dependencies of each
file in sorted order): ``"\\n"``, a line of 80 ``=``, ``"MSG: <dep>"`` and the
dependency's text. Dependency names are written as the field type spells them
(``std_msgs/Header``) or, for a bare name, ``<package of the file>/<Name>``.
This module reproduces that byte for byte.
"""

from __future__ import annotations

import re
import sys
from functools import lru_cache
from pathlib import Path

from ..errors import StewartError
from ..install import install_prefixes

SEPARATOR = "=" * 80

# Same pattern rosbag2 uses to find field types in .msg text.
_FIELD_TYPE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
_PRIMITIVES = frozenset(
    "bool byte char float32 float64 int8 uint8 int16 uint16 int32 uint32 int64 uint64 string".split()
)
_NAME = r"[a-zA-Z][a-zA-Z0-9_]*"
_TYPE_2 = re.compile(rf"^({_NAME})/({_NAME})$")
_TYPE_3 = re.compile(rf"^({_NAME})/({_NAME})/({_NAME})$")
_MAX_DEPTH = 50


class MessageDefinitionError(StewartError):
    """A message type's .msg file could not be found or its name is malformed."""


def _prefixes() -> list[Path]:
    return [Path(p) for p in install_prefixes()]


def split_type(type_name: str) -> tuple[str, str, str]:
    """``pkg/Type`` or ``pkg/msg/Type`` -> (pkg, 'msg', Type)."""
    if m := _TYPE_2.match(type_name):
        return m.group(1), "msg", m.group(2)
    if m := _TYPE_3.match(type_name):
        return m.group(1), m.group(2), m.group(3)
    raise MessageDefinitionError(f"invalid message type name {type_name!r}")


def msg_path(type_name: str) -> Path:
    """Installed .msg file of ``type_name`` (first ament prefix that has it)."""
    pkg, ns, name = split_type(type_name)
    for prefix in _prefixes():
        candidate = prefix / "share" / pkg / ns / f"{name}.msg"
        if candidate.is_file():
            return candidate
    raise MessageDefinitionError(
        f"no .msg file for {type_name!r} under AMENT_PREFIX_PATH or {sys.prefix}"
    )


@lru_cache(maxsize=256)
def _msg_text(type_name: str) -> str:
    return msg_path(type_name).read_bytes().decode("utf-8")


def msg_dependencies(text: str, package: str) -> list[str]:
    """Non-primitive field types of .msg ``text``, sorted, as rosbag2 names them."""
    deps = set()
    for m in _FIELD_TYPE.finditer(text):
        field_type = m.group(1)
        if field_type in _PRIMITIVES:
            continue
        deps.add(field_type if "/" in field_type else f"{package}/{field_type}")
    return sorted(deps)


@lru_cache(maxsize=256)
def full_message_definition(type_name: str) -> str:
    """The complete ``ros2msg`` definition text rosbag2 stores for ``type_name``."""
    seen: set[str] = set()

    def append(name: str, depth: int) -> str:
        if depth <= 0:
            raise MessageDefinitionError(f"recursion too deep resolving {type_name!r}")
        text = _msg_text(name)
        out = text
        for dep in msg_dependencies(text, split_type(name)[0]):
            if dep not in seen:
                seen.add(dep)
                out += f"\n{SEPARATOR}\nMSG: {dep}\n" + append(dep, depth - 1)
        return out

    return append(type_name, _MAX_DEPTH)


def _first_field_type(text: str) -> str | None:
    for raw in text.splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.split()
        if len(parts) >= 2 and "=" in line and "=" not in parts[0]:
            # A constant: "type NAME=value"; not a field.
            if "=" in parts[1] or (len(parts) > 2 and parts[2].startswith("=")):
                continue
        return parts[0]
    return None


@lru_cache(maxsize=256)
def has_header_first(type_name: str) -> bool:
    """True when the first field of ``type_name`` is a std_msgs/Header (stamp at CDR offset 4)."""
    try:
        first = _first_field_type(_msg_text(type_name))
    except MessageDefinitionError:
        return False
    return first in ("std_msgs/Header", "Header" if type_name.startswith("std_msgs/") else "")
