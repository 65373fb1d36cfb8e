"""Another node's answers about its parameters (rcl_interfaces get_parameters and describe_parameters) as plain
Python values, for a client that follows that node's settings (the planning UI follows the vibration planner's)."""

from __future__ import annotations

import math
from collections.abc import Callable

from rcl_interfaces.srv import DescribeParameters, GetParameters
from rclpy.parameter import parameter_value_to_python

from ..errors import MalformedMessageError


def parameter_values(names, values) -> dict:
    """{name: Python value} of a get_parameters answer (rcl_interfaces ParameterValue per asked name);
    MalformedMessageError when the counts differ or a value's type is unknown."""
    if len(values) != len(names):
        raise MalformedMessageError(f"{len(values)} values for {len(names)} names", field="values", kind="length")
    out = {}
    for name, value in zip(names, values, strict=True):
        try:
            python = parameter_value_to_python(value)
        except (RuntimeError, ValueError, TypeError) as exc:
            raise MalformedMessageError(f"{name}: {exc}", field=name, kind="type") from None
        out[name] = list(python) if hasattr(python, "tolist") or isinstance(python, (list, tuple)) else python
    return out


def declared_ranges(descriptors, names) -> dict[str, tuple[float, float]]:
    """{name: (low, high)} of the floating-point ranges a describe_parameters answer declares for ``names``
    (rcl_interfaces ParameterDescriptor each); parameters without a finite range are left out."""
    return {d.name: (d.floating_point_range[0].from_value, d.floating_point_range[0].to_value)
            for d in descriptors if d.name in names and d.floating_point_range and
            math.isfinite(d.floating_point_range[0].from_value) and math.isfinite(d.floating_point_range[0].to_value)}


def ask_parameters(get, describe, names: list[str], got: Callable[[dict], None],
                   described: Callable[[dict], None], malformed: Callable[[MalformedMessageError], None]) -> None:
    """Ask another node for ``names`` through its get_parameters and describe_parameters clients (rclpy clients;
    each only if its server is ready, no waiting): ``got({name: value})`` with the values (a
    MalformedMessageError it or the answer raises goes to ``malformed``), ``described({name: (low, high)})`` with
    the declared ranges. A failed call is dropped: the caller asks again."""
    if get.service_is_ready():
        def values_answered(future) -> None:
            if future.exception() is None:
                try:
                    got(parameter_values(names, future.result().values))
                except MalformedMessageError as exc:
                    malformed(exc)
        get.call_async(GetParameters.Request(names=names)).add_done_callback(values_answered)
    if describe.service_is_ready():
        def ranges_answered(future) -> None:
            if future.exception() is None:
                described(declared_ranges(future.result().descriptors, names))
        describe.call_async(DescribeParameters.Request(names=names)).add_done_callback(ranges_answered)
