"""QoS profiles in rosbag2's ``offered_qos_profiles`` YAML form (metadata version 9, Jazzy).

rosbag2 serialises a list of profiles with yaml-cpp: policies as rmw strings
(``keep_last``, ``reliable``, ``volatile``, ``automatic``, ``unknown``, ...),
durations as ``{sec, nsec}``; an infinite duration is
``sec: 9223372036, nsec: 854775807``. ``dump_qos_profiles`` writes the same
block layout yaml-cpp's ``YAML::Dump`` does (no trailing newline).
"""

from __future__ import annotations

from dataclasses import dataclass

import yaml

INFINITE_DURATION_NS = 2**63 - 1
_NS = 1_000_000_000

HISTORY = ("system_default", "keep_last", "keep_all", "unknown")
RELIABILITY = ("system_default", "reliable", "best_effort", "unknown", "best_available")
DURABILITY = ("system_default", "transient_local", "volatile", "unknown", "best_available")
LIVELINESS = ("system_default", "automatic", "manual_by_topic", "unknown", "best_available")


@dataclass(frozen=True)
class QosProfile:
    """One offered QoS profile; policy names are rmw's lower-case strings, durations in ns."""

    history: str = "keep_last"
    depth: int = 10
    reliability: str = "reliable"
    durability: str = "volatile"
    deadline_ns: int = INFINITE_DURATION_NS
    lifespan_ns: int = INFINITE_DURATION_NS
    liveliness: str = "automatic"
    liveliness_lease_duration_ns: int = INFINITE_DURATION_NS
    avoid_ros_namespace_conventions: bool = False

    def __post_init__(self):
        for value, allowed, what in (
            (self.history, HISTORY, "history"),
            (self.reliability, RELIABILITY, "reliability"),
            (self.durability, DURABILITY, "durability"),
            (self.liveliness, LIVELINESS, "liveliness"),
        ):
            if value not in allowed:
                raise ValueError(f"unknown {what} policy {value!r}; expected one of {allowed}")


def _duration_lines(key: str, ns: int) -> list[str]:
    sec, nsec = divmod(int(ns), _NS)
    return [f"  {key}:", f"    sec: {sec}", f"    nsec: {nsec}"]


def dump_qos_profiles(profiles: list[QosProfile]) -> str:
    """YAML text rosbag2 stores in the channel metadata ``offered_qos_profiles``."""
    if not profiles:
        return "[]"
    lines: list[str] = []
    for p in profiles:
        lines += [
            f"- history: {p.history}",
            f"  depth: {int(p.depth)}",
            f"  reliability: {p.reliability}",
            f"  durability: {p.durability}",
            *_duration_lines("deadline", p.deadline_ns),
            *_duration_lines("lifespan", p.lifespan_ns),
            f"  liveliness: {p.liveliness}",
            *_duration_lines("liveliness_lease_duration", p.liveliness_lease_duration_ns),
            f"  avoid_ros_namespace_conventions: {'true' if p.avoid_ros_namespace_conventions else 'false'}",
        ]
    return "\n".join(lines)


def _policy(value, names: tuple[str, ...]) -> str:
    # Metadata versions < 9 stored integers (the rmw enum values).
    if isinstance(value, int):
        if names is LIVELINESS:
            return {0: "system_default", 1: "automatic", 3: "manual_by_topic"}.get(value, "unknown")
        return names[value] if 0 <= value < len(names) else "unknown"
    return str(value)


def _duration(node) -> int:
    return int(node["sec"]) * _NS + int(node["nsec"])


def parse_qos_profiles(text: str) -> list[QosProfile]:
    """Inverse of :func:`dump_qos_profiles` (also accepts older integer-enum profiles)."""
    data = yaml.safe_load(text) if text and text.strip() else []
    out = []
    for item in data or []:
        out.append(
            QosProfile(
                history=_policy(item["history"], HISTORY),
                depth=int(item["depth"]),
                reliability=_policy(item["reliability"], RELIABILITY),
                durability=_policy(item["durability"], DURABILITY),
                deadline_ns=_duration(item["deadline"]),
                lifespan_ns=_duration(item["lifespan"]),
                liveliness=_policy(item["liveliness"], LIVELINESS),
                liveliness_lease_duration_ns=_duration(item["liveliness_lease_duration"]),
                avoid_ros_namespace_conventions=bool(item["avoid_ros_namespace_conventions"]),
            )
        )
    return out


def request_for_offers(offers: list[QosProfile], depth: int) -> QosProfile:
    """The subscription QoS rosbag2 requests for these offers (reliable/transient only if all are)."""
    reliable = bool(offers) and all(o.reliability == "reliable" for o in offers)
    transient = bool(offers) and all(o.durability == "transient_local" for o in offers)
    return QosProfile(
        history="keep_last",
        depth=depth,
        reliability="reliable" if reliable else "best_effort",
        durability="transient_local" if transient else "volatile",
    )


def offer_for_replay(recorded: list[QosProfile], depth: int = 10) -> QosProfile:
    """Publisher QoS for replay: the recorded offer (keep_last ``depth``) when all agree."""
    if not recorded:
        return QosProfile(depth=depth)
    first = recorded[0]
    if all(
        (r.reliability, r.durability) == (first.reliability, first.durability) for r in recorded
    ):
        rel = first.reliability if first.reliability in ("reliable", "best_effort") else "reliable"
        dur = first.durability if first.durability in ("volatile", "transient_local") else "volatile"
        return QosProfile(depth=depth, reliability=rel, durability=dur)
    return QosProfile(depth=depth)
