"""Parameters declared once: the specs' checks, the tables, the generated docs, the suite's parameter file,
and real nodes (rclpy in process) declaring and validating exactly their table."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from stewart_vibration.errors import InvalidInputError
from stewart_vibration.install import default_config_dir
from stewart_vibration.parameters.docs import parameters_markdown
from stewart_vibration.parameters.spec import ParameterSpec
from stewart_vibration.parameters.tables import NODE_PARAMETERS, spec_of
from stewart_vibration.safe_yaml import load_yaml

ROOT = Path(__file__).resolve().parents[1]


def test_a_double_takes_an_integer_as_that_number_and_refuses_what_is_no_number_in_range():
    spec = ParameterSpec("rate_hz", "double", 1.0, "a rate", "Hz", 0.0, 10.0)
    assert spec.checked(3) == 3.0 and isinstance(spec.checked(3), float)
    for bad, words in ((True, "must be a number"), ("2", "must be a number"), (math.nan, "is outside [0, 10] Hz"),
                       (10.5, "'rate_hz' = 10.5 is outside [0, 10] Hz (a rate)"), (-1e-9, "is outside")):
        with pytest.raises(InvalidInputError) as refused:
            spec.checked(bad)
        assert words in str(refused.value)


def test_integers_bools_strings_and_lists_are_checked_by_kind():
    count = ParameterSpec("count", "integer", 10, "a count", "", 1, 1000)
    assert count.checked(1000) == 1000
    for bad in (1.5, True, 0, 1001, "3"):
        with pytest.raises(InvalidInputError, match="'count'"):
            count.checked(bad)
    flag = ParameterSpec("flag", "bool", False, "a flag")
    assert flag.checked(True) is True
    with pytest.raises(InvalidInputError, match="true or false"):
        flag.checked(1)
    with pytest.raises(InvalidInputError, match="must be a string"):
        ParameterSpec("name", "string", "", "a name").checked(3)
    topics = ParameterSpec("topics", "string_array", [""], "topics")
    assert topics.checked(("a", "b")) == ["a", "b"]
    with pytest.raises(InvalidInputError, match="list of strings"):
        topics.checked(["a", 1])


def test_a_spec_refuses_a_default_outside_its_own_range_and_a_range_on_a_string():
    with pytest.raises(InvalidInputError, match="outside"):
        ParameterSpec("x", "double", 5.0, "x", "", 0.0, 1.0)
    with pytest.raises(ValueError, match="only numbers have a range"):
        ParameterSpec("x", "string", "", "x", "", 0.0, 1.0)
    with pytest.raises(ValueError, match="kind"):
        ParameterSpec("x", "float", 0.0, "x")
    with pytest.raises(ValueError, match="not both"):
        ParameterSpec("x", "double", 0.0, "x", read_only=True, at_configure=True)
    assert ParameterSpec("x", "double", 0.0, "x", at_configure=True).settable == "while unconfigured"


def test_every_table_names_each_parameter_once_with_a_description():
    for node, specs in NODE_PARAMETERS.items():
        names = [s.name for s in specs]
        assert len(names) == len(set(names)), node
        assert all(s.description for s in specs), node
    assert spec_of("kinematics", "guard_force_n").unit == "N"
    with pytest.raises(KeyError, match="no parameter 'nope'"):
        spec_of("kinematics", "nope")


def test_docs_parameters_md_is_the_generated_one():
    """docs/parameters.md is what parameters.docs writes from the tables (regenerate it when a table changes:
    python -m stewart_vibration.parameters.docs > docs/parameters.md)."""
    text = (ROOT / "docs" / "parameters.md").read_text()
    assert text == parameters_markdown()
    for node, specs in NODE_PARAMETERS.items():  # each parameter in its node's section, with its default
        section = text.split(f"## {node}\n", 1)[1].split("\n## ", 1)[0]
        for spec in specs:
            assert f"| `{spec.name}` | {spec.kind} | `" in section, (node, spec.name)


def test_the_suite_parameter_file_sets_only_declared_parameters_to_valid_values():
    """config/suite_params.yaml (the bring-up's and the launch file's): every key under a node is a parameter of
    that node's table and its value passes the node's check; the values of this file are what a suite runs."""
    tree = load_yaml(default_config_dir() / "suite_params.yaml", "suite parameters")
    checked = 0
    for key, section in tree.items():
        values = section["ros__parameters"]
        if key == "/**":
            assert set(values) == {"use_sim_time"} and values["use_sim_time"] is True
            continue
        node = key.removeprefix("/**/")
        assert node in NODE_PARAMETERS, f"{key}: no such node"
        for name, value in values.items():
            spec_of(node, name).checked(value)
            checked += 1
    assert checked >= 8


def test_a_wrong_value_in_the_suite_parameter_file_would_be_caught():
    """The check above can fail: a value outside its range and an unknown name are refused."""
    with pytest.raises(InvalidInputError, match="'physics_rate_hz' = 1e\\+06 is outside"):
        spec_of("hardware_emulator", "physics_rate_hz").checked(1e6)
    with pytest.raises(KeyError):
        spec_of("kinematics", "speed_scale_typo")


@pytest.fixture
def start_node(ros_domain):
    """Makes a real node of a node class with command-line overrides (``name:=value``), in this process on
    this test's own ROS domain; shuts rclpy down after the test."""
    import rclpy

    nodes = []

    def start(node_class, overrides: list[str]):
        rclpy.init(args=["--ros-args"] + [part for o in overrides for part in ("-p", o)])
        node = node_class()
        nodes.append(node)
        return node

    yield start
    for node in nodes:
        node.destroy_node()
    rclpy.try_shutdown()


def test_a_real_node_declares_exactly_its_table_with_descriptors_and_checks_sets(start_node):
    from rcl_interfaces.msg import ParameterType
    from rclpy.parameter import Parameter

    from stewart_vibration.nodes.kinematics_node import KinematicsNode

    node = start_node(KinematicsNode, ["guard_force_n:=100", "batch_size:=20"])
    declared = set(node.get_parameters_by_prefix("")) - {"use_sim_time", "start_type_description_service"}
    assert declared == {s.name for s in NODE_PARAMETERS["kinematics"]}
    force = node.get_parameter("guard_force_n")
    assert force.value == 100.0 and force.type_ == Parameter.Type.DOUBLE  # an integer given for a double
    assert node.get_parameter("batch_size").value == 20
    described = node.describe_parameter("guard_force_n")
    assert described.type == ParameterType.PARAMETER_DOUBLE and "[N]" in described.description
    assert described.floating_point_range[0].to_value == spec_of("kinematics", "guard_force_n").high
    assert node.describe_parameter("batch_size").read_only
    results = node.set_parameters([Parameter("guard_force_n", Parameter.Type.DOUBLE, 1e5)])
    assert not results[0].successful and "guard_force_n" in results[0].reason
    results = node.set_parameters([Parameter("batch_size", Parameter.Type.INTEGER, 5)])
    assert not results[0].successful  # read only
    results = node.set_parameters([Parameter("guard_force_n", Parameter.Type.DOUBLE, 150.0)])
    assert results[0].successful and node.guard.force_limit == 150.0  # applied after the check
    results = node.set_parameters([Parameter("guard_force_n", Parameter.Type.INTEGER, 120)])  # ros2 param set 120
    assert results[0].successful and node.get_parameter("guard_force_n").type_ == Parameter.Type.DOUBLE
    assert node.guard.force_limit == 120.0
    results = node.set_parameters([Parameter("guard_force_n", Parameter.Type.STRING, "strong")])
    assert not results[0].successful and node.guard.force_limit == 120.0


@pytest.mark.parametrize("override, words", [
    ("guard_force_n:=nope", "'guard_force_n' must be a number, got 'nope'"),
    ("guard_force_n:=-1", "'guard_force_n' = -1 is outside [0, 5000] N"),
    ("batch_size:=2.5", "'batch_size' must be an integer"),
    ("tissue_config:=3", "'tissue_config' must be a string"),
])
def test_a_real_node_refuses_a_bad_start_value_naming_the_parameter(start_node, override, words):
    from stewart_vibration.nodes.kinematics_node import KinematicsNode

    with pytest.raises(ValueError) as refused:
        start_node(KinematicsNode, [override])
    assert words in str(refused.value)
