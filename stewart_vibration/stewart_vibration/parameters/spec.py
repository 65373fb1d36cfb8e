"""One node parameter, declared once: its name, type, default, range, whether it is read only, what it means
and its unit (pure: the nodes build their rclpy descriptors from it, the docs are generated from it, the
suite's parameter file is checked against it).

``ParameterSpec.checked(value)`` is the one validation of a value: at start (an override from the command
line or a params file) and on every set at run time, so both refuse the same values with the same reason.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import InvalidInputError

KINDS = ("double", "integer", "string", "bool", "string_array")
INTEGER_LIMIT = 2**63 - 1  # a ROS integer parameter is an int64


@dataclass(frozen=True)
class ParameterSpec:
    """A node parameter: ``kind`` one of KINDS; ``low`` / ``high`` the inclusive range of a number (None: no
    bound below / above); ``unit`` its SI unit ("" for none); ``read_only``: read once at start, ``ros2 param
    set`` is refused; ``at_configure``: a lifecycle node's parameter read at configure, settable only while the
    node is unconfigured (the node refuses a set otherwise, saying so); ``description`` for people (``ros2 param
    describe``)."""

    name: str
    kind: str
    default: object
    description: str
    unit: str = ""
    low: float | None = None
    high: float | None = None
    read_only: bool = False
    at_configure: bool = False

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"parameter {self.name!r}: kind {self.kind!r} is not one of {KINDS}")
        if self.kind not in ("double", "integer") and (self.low is not None or self.high is not None):
            raise ValueError(f"parameter {self.name!r}: only numbers have a range")
        if self.read_only and self.at_configure:
            raise ValueError(f"parameter {self.name!r}: read at start or at configure, not both")
        self.checked(self.default)  # a table whose default is outside its own range fails at import

    @property
    def bounds(self) -> tuple[float, float]:
        """(low, high) with the open ends as -inf / inf (an integer's as the int64 range)."""
        if self.kind == "integer":
            return (-INTEGER_LIMIT - 1 if self.low is None else self.low,
                    INTEGER_LIMIT if self.high is None else self.high)
        return (-math.inf if self.low is None else self.low, math.inf if self.high is None else self.high)

    def checked(self, value):
        """``value`` as this parameter's type (an integer given for a double is that number) if it is of the
        right kind and within the range; InvalidInputError naming the parameter, the value and the range
        otherwise (a NaN is outside every range)."""
        kind = self.kind
        if kind == "double":
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise InvalidInputError(f"parameter {self.name!r} must be a number, got {value!r}")
            value = float(value)
        elif kind == "integer":
            if isinstance(value, bool) or not isinstance(value, int):
                raise InvalidInputError(f"parameter {self.name!r} must be an integer, got {value!r}")
        elif kind == "bool":
            if not isinstance(value, bool):
                raise InvalidInputError(f"parameter {self.name!r} must be true or false, got {value!r}")
            return value
        elif kind == "string":
            if not isinstance(value, str):
                raise InvalidInputError(f"parameter {self.name!r} must be a string, got {value!r}")
            return value
        else:
            if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
                raise InvalidInputError(f"parameter {self.name!r} must be a list of strings, got {value!r}")
            return list(value)
        low, high = self.bounds
        if not low <= value <= high:  # also refuses nan
            raise InvalidInputError(f"parameter {self.name!r} = {value:g} is outside [{low:g}, {high:g}]"
                                    f"{f' {self.unit}' if self.unit else ''} ({self.description})")
        return value

    @property
    def settable(self) -> str:
        """When a set is taken: "yes" (while the node runs), "read only" or "while unconfigured"."""
        return "read only" if self.read_only else "while unconfigured" if self.at_configure else "yes"

    @property
    def shown_default(self) -> str:
        """The default as the docs show it (YAML-like: true, '' for an empty string, [] for an empty list)."""
        value = self.default
        if isinstance(value, bool):
            return "true" if value else "false"
        if isinstance(value, str):
            return repr(value) if value == "" else value
        if isinstance(value, (list, tuple)):
            return "[]" if not [v for v in value if v] else ", ".join(value)
        return f"{value:g}"
