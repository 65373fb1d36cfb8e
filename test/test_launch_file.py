"""The launch file for ROS installs (launch is not on PyPI: checked statically here)."""

from __future__ import annotations

import ast
import importlib.util
from pathlib import Path

import pytest
import yaml

from stewart_vibration.install import default_config_dir
from stewart_vibration.runtime.suite import SUITE_NODES, SUITE_PARAMS_FILE

ROOT = Path(__file__).resolve().parents[1] / "stewart_vibration"  # the ament_python package directory


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


def test_launch_file_configures_then_activates_the_managed_emulator(monkeypatch):
    """launch is not on PyPI: run generate_launch_description with launch's classes recorded (see
    test_dds_loopback._launch_actions) and check the lifecycle wiring of hardware_emulator."""
    from lifecycle_msgs.msg import Transition
    from test_dds_loopback import _launch_actions

    actions = _launch_actions(monkeypatch, ROOT)
    managed = [a for a in actions if a[0] == "lifecycle_node"]
    assert [a[2]["name"] for a in managed] == ["hardware_emulator"]
    assert any(isinstance(p, dict) and p.get("autostart") is False for p in managed[0][2]["parameters"])
    emits = [a for a in actions if a[0] == "emit"]
    assert [e[2]["event"][2]["transition_id"] for e in emits] == [Transition.TRANSITION_CONFIGURE]
    (handler,) = [a for a in actions if a[0] == "handler"]
    on_transition = handler[1][0]
    assert on_transition[2]["goal_state"] == "inactive"
    (activate,) = on_transition[2]["entities"]
    assert activate[2]["event"][2]["transition_id"] == Transition.TRANSITION_ACTIVATE


def test_launch_file_passes_the_tissue_to_the_emulator_and_kinematics(monkeypatch):
    """tissue_config:=FILE reaches both nodes that use it, as a string ('' = none), like --tissue of the bring-up."""
    from test_dds_loopback import _launch_actions

    actions = _launch_actions(monkeypatch, ROOT)
    (tissue,) = [a for a in actions if a[0] == "arg" and a[1] == ("tissue_config",)]
    assert tissue[2]["default_value"] == ""
    nodes = {a[2]["name"]: a[2]["parameters"][-1] for a in actions if a[0] in ("node", "lifecycle_node")}
    for name in ("hardware_emulator", "kinematics"):
        kind, args, kwargs = nodes[name]["tissue_config"]
        assert kind == "parameter_value" and args[0] == ("config", ("tissue_config",), {})
        assert kwargs["value_type"] is str
    assert "tissue_config" not in nodes["leg_force_estimator"]


def test_launch_file_passes_the_robot_to_every_node_that_reads_one(monkeypatch):
    """robot_config:=FILE reaches every node whose SuiteNode says it reads a robot (optional nodes too), as a
    string ('' = config/robot.yaml), like --robot of the bring-up; the recorder gets none."""
    from test_dds_loopback import _launch_actions

    from stewart_vibration.runtime.suite import OPTIONAL_NODES

    actions = _launch_actions(monkeypatch, ROOT)
    (robot,) = [a for a in actions if a[0] == "arg" and a[1] == ("robot_config",)]
    assert robot[2]["default_value"] == ""
    nodes = {a[2]["name"]: a[2]["parameters"][-1] for a in actions if a[0] in ("node", "lifecycle_node")}
    for spec in SUITE_NODES + list(OPTIONAL_NODES.values()):
        if spec.robot_config:
            kind, args, kwargs = nodes[spec.name]["robot_config"]
            assert kind == "parameter_value" and args[0] == ("config", ("robot_config",), {})
            assert kwargs["value_type"] is str
        else:
            assert "robot_config" not in nodes[spec.name]


def test_every_launch_argument_says_what_it_does(monkeypatch):
    """`ros2 launch -s` shows each argument's description: none is left without one."""
    from test_dds_loopback import _launch_actions

    arguments = [a for a in _launch_actions(monkeypatch, ROOT) if a[0] == "arg"]
    assert len(arguments) >= 7
    assert all(a[2].get("description", "").strip() for a in arguments), [a[1] for a in arguments]


def test_launch_file_under_the_real_launch_package():
    """With launch and launch_ros importable (a ROS install, or the real tools built into a venv; neither is
    on PyPI), the file is evaluated by them: every argument declared with its description and default, one
    node per suite node (the emulator managed), and launch's introspector renders the whole description."""
    launch = pytest.importorskip("launch", reason="launch is not on PyPI (a ROS install has it)")
    launch_ros = pytest.importorskip("launch_ros", reason="launch_ros is not on PyPI (a ROS install has it)")
    spec = importlib.util.spec_from_file_location("suite_launch", ROOT / "launch" / "stewart_vibration.launch.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    description = module.generate_launch_description()
    assert isinstance(description, launch.LaunchDescription)
    arguments = description.get_launch_arguments()
    assert {a.name for a in arguments} >= {"namespace", "real_time_factor", "output_dir", "ui", "robot_config"}
    assert all(a.description.strip() and a.description != "no description given" for a in arguments)
    nodes = [e for e in description.entities if isinstance(e, launch_ros.actions.Node)]
    managed = [n for n in nodes if isinstance(n, launch_ros.actions.LifecycleNode)]
    assert len(nodes) >= len(SUITE_NODES) and len(managed) == 1
    executables = {n.node_executable for n in nodes}
    assert {s.executable for s in SUITE_NODES} <= executables <= console_scripts()
    assert "hardware_emulator" in launch.LaunchIntrospector().format_launch_description(description)
