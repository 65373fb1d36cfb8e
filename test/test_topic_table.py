"""The repository's one topic table (docs/interfaces.md, "ROS graph") against the nodes' code, read with ast:
every topic a node module publishes or subscribes by name is a row that names that node; every row's
publisher publishes it, with the type and history depth the row gives; every node a row says reads a topic
names it in its code (some subscribe from a list: the UI's streams, the emulator's pace, the runner's poses).
The recorder and the Foxglove bridge subscribe to what they discover, so only their publishing is checked."""

from __future__ import annotations

import ast
import re
from collections import defaultdict
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
NODES = REPO / "stewart_vibration" / "stewart_vibration" / "nodes"
DOC = REPO / "docs" / "interfaces.md"

# the table's names for the suite's processes -> the node modules that make up each one
MODULES = {
    "emulator": ("hardware_emulator_node", "emulator_command_server"),
    "kinematics": ("kinematics_node", "calibration_server"),
    "planner": ("vibration_planner_node",),
    "estimator": ("leg_force_estimator_node",),
    "UI": ("planning_ui_node",),
    "runner": ("suite_client",),
    "Foxglove bridge": ("foxglove_bridge_node",),
    "recorder": ("mcap_recorder_node",),
    "every node": ("diagnostics",),
}
NOT_NODES = {"run summary", "tests", "RViz/Foxglove", "every node on sim time"}  # readers of no node module here
# modules that publish or subscribe what their user names, not a topic of the suite
GENERIC = {"mcap_replay_node", "service_calls", "topic_listener"}
DEPTHS = {"STREAM_DEPTH": "3000", "CLOCK_DEPTH": "100", "STATUS_QOS": "transient local, 1"}


def table_rows() -> dict[str, dict]:
    """topic -> {type, qos, from, to: {name: note}} of the ROS graph table."""
    text = DOC.read_text()
    section = text[text.index("## ROS graph"):]
    section = section[:section.index("\n## ", 3)]
    rows = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 4 or not cells[0].startswith("`"):
            continue
        topic = cells[0].strip("`")
        source, _, readers = cells[3].partition("->")
        to = {}
        for reader in re.split(r",\s*(?![^()]*\))", readers):  # commas outside parentheses
            name = re.sub(r"\s*\(.*\)\s*$", "", reader.strip())
            to[name] = reader.strip()
        rows[topic] = {"type": cells[1].split()[0].strip(":"), "qos": cells[2], "from": source.strip(), "to": to}
    return rows


def node_code() -> tuple[dict, dict, dict]:
    """(publishers, subscribers: topic -> {module: depth or None}; names: module -> every non-docstring string
    constant in it) of nodes/*.py."""
    pubs: dict = defaultdict(dict)
    subs: dict = defaultdict(dict)
    names: dict = {}
    for path in sorted(NODES.glob("*.py")):
        tree = ast.parse(path.read_text())
        docstrings = {id(n.value) for n in ast.walk(tree)
                      if isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant)}
        names[path.stem] = {n.value for n in ast.walk(tree)
                            if isinstance(n, ast.Constant) and isinstance(n.value, str) and id(n) not in docstrings}
        for call in ast.walk(tree):
            if not (isinstance(call, ast.Call) and isinstance(call.func, ast.Attribute)
                    and call.func.attr in ("create_publisher", "create_subscription") and len(call.args) >= 2):
                continue
            topic = call.args[1]
            if not (isinstance(topic, ast.Constant) and isinstance(topic.value, str)):
                continue
            kind = call.args[0]
            type_name = kind.id if isinstance(kind, ast.Name) else None
            depth_arg = call.args[2] if call.func.attr == "create_publisher" else call.args[3]
            depth = (str(depth_arg.value) if isinstance(depth_arg, ast.Constant)
                     else DEPTHS.get(depth_arg.id) if isinstance(depth_arg, ast.Name) else None)
            target = pubs if call.func.attr == "create_publisher" else subs
            target[topic.value][path.stem] = (type_name, depth)
    return pubs, subs, names


def node_of(module: str) -> str:
    return next(name for name, modules in MODULES.items() if module in modules)


ROWS = table_rows()
PUBS, SUBS, NAMES = node_code()


def test_the_table_is_read_and_the_readme_has_no_second_copy():
    assert len(ROWS) >= 15 and "legs/joint_states" in ROWS
    assert not re.search(r"^\| topic \|", (REPO / "README.md").read_text(), re.MULTILINE)


@pytest.mark.parametrize("topic", sorted(set(PUBS) | set(SUBS)))
def test_every_topic_a_node_uses_by_name_is_a_row_naming_that_node(topic):
    if all(module in GENERIC for module in {*PUBS[topic], *SUBS[topic]}):
        pytest.skip(f"{topic}: only generic tools use it")
    if "/_action/" in topic:
        pytest.skip(f"{topic}: an action's own topic (the actions are listed with the services)")
    assert topic in ROWS, f"{topic} is used by {sorted({*PUBS[topic], *SUBS[topic]})} but not in {DOC.name}"
    row = ROWS[topic]
    for module, (type_name, depth) in PUBS[topic].items():
        if module in GENERIC:
            continue
        assert node_of(module) == row["from"], (topic, module, row["from"])
        assert type_name is None or row["type"].endswith("/" + type_name), (topic, type_name, row["type"])
        assert depth is None or row["qos"] == f"reliable, {depth}", (topic, depth, row["qos"])
    for module in SUBS[topic]:
        if module not in GENERIC:
            assert node_of(module) in row["to"], (topic, module, sorted(row["to"]))


@pytest.mark.parametrize("topic", sorted(ROWS))
def test_every_row_is_published_and_read_as_it_says(topic):
    row = ROWS[topic]
    publishers = {node_of(m) for m in PUBS.get(topic, {}) if m not in GENERIC}
    assert publishers == {row["from"]}, (topic, publishers, row["from"])
    for reader in row["to"]:
        if reader in NOT_NODES:
            continue
        assert reader in MODULES, f"{topic}: unknown reader {reader!r}"
        if reader in ("recorder", "Foxglove bridge"):
            continue  # they subscribe to what they discover
        assert any(topic in NAMES[m] for m in MODULES[reader]), f"{topic}: {reader} never names it"
