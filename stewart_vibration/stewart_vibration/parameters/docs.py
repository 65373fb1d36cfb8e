"""docs/parameters.md from the parameter tables (pure): one table per node with each parameter's type,
default, range, unit, whether it can be set while the node runs, and its description.

Regenerate with ``python -m stewart_vibration.parameters.docs > docs/parameters.md``; a test fails while the
file differs from what this writes.
"""

from __future__ import annotations

import math
import sys

from .spec import ParameterSpec
from .tables import NODE_PARAMETERS

HEADER = """# Node parameters

Generated from `stewart_vibration/stewart_vibration/parameters/tables.py` (the one place each parameter is
declared) by `python -m stewart_vibration.parameters.docs > docs/parameters.md`; a test keeps the two equal.

Every node declares these with their type, range and description (`ros2 param describe` shows them) and
validates every value against the same spec at start and on every `ros2 param set`: a value of the wrong
type or outside its range is refused with a reason naming the parameter (an integer is accepted for a
double, e.g. `-p real_time_factor:=0`). "read only" parameters are read once at start: `ros2 param set` says
so instead of silently ignoring a value. The hardware emulator's "while unconfigured" parameters are read at
configure: set them after `cleanup` and before `configure` (a set while it is configured is refused, saying
so). `config/suite_params.yaml`, the suite's parameter file, is checked against these tables by a test.
"""


def _bound(value: float | None) -> str:
    if isinstance(value, int):
        return str(value)
    return "" if value is None or not math.isfinite(value) else f"{value:g}"


def range_text(spec: ParameterSpec) -> str:
    """"[low, high]" of a number ("" for other kinds; an open end is left empty)."""
    if spec.kind not in ("double", "integer") or (spec.low is None and spec.high is None):
        return ""
    return f"[{_bound(spec.low)}, {_bound(spec.high)}]"


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def node_table(node: str, specs) -> str:
    """The markdown section of one node."""
    lines = [f"## {node}", "", "| parameter | type | default | range | unit | set while running | description |",
             "|---|---|---|---|---|---|---|"]
    for spec in specs:
        lines.append(f"| `{spec.name}` | {spec.kind} | `{_cell(spec.shown_default)}` | {range_text(spec)} | "
                     f"{spec.unit} | {spec.settable} | {_cell(spec.description)} |")
    return "\n".join(lines) + "\n"


def parameters_markdown() -> str:
    """The whole of docs/parameters.md."""
    return HEADER + "".join("\n" + node_table(node, specs) for node, specs in NODE_PARAMETERS.items())


if __name__ == "__main__":
    sys.stdout.write(parameters_markdown())
