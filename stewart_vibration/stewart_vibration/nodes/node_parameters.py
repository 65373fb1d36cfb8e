"""A node's parameters declared from their specs (parameters.tables) through rclpy: descriptors with the
type, the description with its unit, the range and the read-only flag, and every later set checked against
the same specs. Values in the unit each spec names."""

from __future__ import annotations

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType, SetParametersResult
from rclpy.parameter import Parameter

from ..errors import InvalidInputError
from ..parameters.spec import ParameterSpec

PARAMETER_TYPES = {"double": ParameterType.PARAMETER_DOUBLE, "integer": ParameterType.PARAMETER_INTEGER,
                   "string": ParameterType.PARAMETER_STRING, "bool": ParameterType.PARAMETER_BOOL,
                   "string_array": ParameterType.PARAMETER_STRING_ARRAY}


def descriptor_of(spec: ParameterSpec) -> ParameterDescriptor:
    """The rclpy descriptor of a parameter spec: its type, description (with the unit), read-only flag and
    range (what ``ros2 param describe`` shows and rclpy enforces on a set)."""
    description = f"{spec.description} [{spec.unit}]" if spec.unit else spec.description
    descriptor = ParameterDescriptor(name=spec.name, type=PARAMETER_TYPES[spec.kind], description=description,
                                     read_only=spec.read_only)
    low, high = spec.bounds
    if spec.kind == "double" and (spec.low is not None or spec.high is not None):
        descriptor.floating_point_range = [FloatingPointRange(from_value=float(low), to_value=float(high), step=0.0)]
    elif spec.kind == "integer":
        descriptor.integer_range = [IntegerRange(from_value=int(low), to_value=int(high), step=1)]
    return descriptor


def declare_spec(node, spec: ParameterSpec):
    """Declare one parameter from its spec and return its value.

    The value given at start (``-p name:=value``, a params file) is read through rclpy's public API: a first,
    dynamically typed declaration takes whatever was given; it is checked against the spec (an integer for a
    double is that number) and then declared with the spec's descriptor, overrides ignored, so rclpy's own
    type check never refuses a value the spec accepts. ValueError naming the parameter for a value of the
    wrong kind or out of range (the node then exits with that line)."""
    loose = ParameterDescriptor(description=spec.description, dynamic_typing=True)
    given = node.declare_parameter(spec.name, spec.default, loose).value
    node.undeclare_parameter(spec.name)
    try:
        value = spec.checked(given)
    except InvalidInputError as exc:
        raise ValueError(str(exc)) from None
    if spec.kind == "string_array" and not value:
        value = [""]  # rclpy cannot type an empty list; the nodes drop empty names
    return node.declare_parameter(spec.name, value, descriptor_of(spec), ignore_override=True).value


def declare_table(node, specs) -> dict:
    """Declare every parameter of a node's table (parameters.tables) and check every later set against the
    same specs (an on-set callback: a refused value's reason names the parameter); an integer set on a double
    (``ros2 param set ... real_time_factor 0``) is taken as that number (a pre-set callback). Returns
    {name: value}."""
    values = {spec.name: declare_spec(node, spec) for spec in specs}
    by_name = {spec.name: spec for spec in specs}
    doubles = {spec.name for spec in specs if spec.kind == "double"}

    def integers_as_doubles(params) -> list:
        return [Parameter(p.name, Parameter.Type.DOUBLE, float(p.value))
                if p.name in doubles and p.type_ == Parameter.Type.INTEGER else p for p in params]

    def check_sets(params) -> SetParametersResult:
        for param in params:
            spec = by_name.get(param.name)
            if spec is None:
                continue
            try:
                spec.checked(param.value)
            except InvalidInputError as exc:
                return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    node.add_pre_set_parameters_callback(integers_as_doubles)
    node.add_on_set_parameters_callback(check_sets)
    return values


__all__ = [
    "PARAMETER_TYPES",
    "descriptor_of",
    "declare_spec",
    "declare_table",
]
