"""The launch file for ROS installs (launch is not on PyPI: checked statically here)."""

from __future__ import annotations

import ast
from pathlib import Path

import yaml

from stewart_vibration.robot import default_config_dir
from stewart_vibration.suite import SUITE_NODES, SUITE_PARAMS_FILE

ROOT = Path(__file__).resolve().parents[1]


def console_scripts() -> set[str]:
    tree = ast.parse((ROOT / "setup.py").read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign) and any(getattr(t, "id", "") == "CONSOLE_SCRIPTS" for t in node.targets):
            return {ast.literal_eval(e).split("=")[0].strip() for e in node.value.elts}
    raise AssertionError("no CONSOLE_SCRIPTS")


def test_launch_file_compiles_and_uses_the_suite_definition():
    source = (ROOT / "launch" / "stewart_vibration.launch.py").read_text()
    tree = ast.parse(source)
    names = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
    assert {"SUITE_NODES", "SUITE_PARAMS_FILE", "generate_launch_description"} <= names | {
        f.name for f in tree.body if isinstance(f, ast.FunctionDef)}


def test_every_suite_node_is_an_installed_executable_with_a_module():
    scripts = console_scripts()
    for node in SUITE_NODES:
        assert node.executable in scripts
        assert (ROOT / (node.module.replace(".", "/") + ".py")).is_file()


def test_params_file_names_only_suite_nodes_in_any_namespace():
    tree = yaml.safe_load((default_config_dir() / SUITE_PARAMS_FILE).read_text())
    keys = set(tree) - {"/**"}
    assert keys and all(key.startswith("/**/") for key in keys)  # a bare node name matches the root namespace only
    assert {key.removeprefix("/**/") for key in keys} <= {n.name for n in SUITE_NODES}
    for block in tree.values():
        assert "ros__parameters" in block
