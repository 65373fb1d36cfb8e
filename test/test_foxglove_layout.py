"""config/foxglove_layout.json: Foxglove's layout file format (configById + a mosaic tree), every
panel placed and configured, every topic one the suite or the bridge publishes, and the joint indices of the
plots the joints the emulator and the estimator really publish there."""

from __future__ import annotations

import json
import re
from pathlib import Path

from stewart_vibration.nodes.mcap_recorder_node import SUITE_TOPICS
from stewart_vibration.robot import LEG_NAMES, VIB_NAMES

LAYOUT = Path(__file__).resolve().parents[1] / "stewart_vibration" / "config" / "foxglove_layout.json"
NS = "/stewart"
TOPICS = {t if t.startswith("/") else f"{NS}/{t}" for t in SUITE_TOPICS} | {f"{NS}/scene/entities",
                                                                           f"{NS}/scene/transforms"}
STATES = [*LEG_NAMES, *VIB_NAMES]  # legs/joint_states, in the emulator's order
ESTIMATES = list(LEG_NAMES)  # legs/force_estimate


def panels_in(tree) -> list[str]:
    if isinstance(tree, str):
        return [tree]
    assert set(tree) <= {"first", "second", "direction", "splitPercentage"}, tree
    assert tree["direction"] in ("row", "column")
    return panels_in(tree["first"]) + panels_in(tree["second"])


def test_layout_is_a_foxglove_layout_with_every_panel_configured():
    layout = json.loads(LAYOUT.read_text())
    assert set(layout) == {"configById", "globalVariables", "userNodes", "playbackConfig", "layout"}
    placed = panels_in(layout["layout"])
    assert sorted(placed) == sorted(layout["configById"])
    kinds = {p.split("!")[0] for p in placed}
    assert kinds == {"3D", "Plot", "StateTransitions", "RawMessages", "DiagnosticSummary"}


def test_layout_topics_exist_and_plots_pick_the_right_joints():
    config = json.loads(LAYOUT.read_text())["configById"]
    three_d = config["3D!robot"]
    assert three_d["followTf"] == "base"
    assert set(three_d["topics"]) <= TOPICS and f"{NS}/robot_markers" in three_d["topics"]  # recorded runs too
    paths = [s for key, c in config.items() if key.split("!")[0] in ("Plot", "StateTransitions") for s in c["paths"]]
    for series in paths:
        assert series["value"].split(".")[0] in TOPICS, series
    for key in ("RawMessages!vibstatus",):
        assert config[key]["topicPath"] in TOPICS
    assert config["DiagnosticSummary!diag"]["topicToRender"] == "/diagnostics"

    def joints(panel: str, topic: str, field: str, names) -> list[str]:
        found = []
        for s in config[panel]["paths"]:
            m = re.fullmatch(rf"{re.escape(NS)}/{topic}\.{field}\[(\d+)\]", s["value"])
            if m:
                found.append(names[int(m.group(1))])
                assert s["label"].split()[0] == found[-1], s  # the label names the joint plotted
        return found

    assert joints("Plot!vib", "legs/joint_states", "position", STATES) == list(VIB_NAMES)
    assert joints("Plot!forces", "legs/joint_states", "effort", STATES) == list(LEG_NAMES)  # measured
    assert joints("Plot!forces", "legs/force_estimate", "effort", ESTIMATES) == list(LEG_NAMES)  # estimated
