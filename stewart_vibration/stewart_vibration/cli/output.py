"""Plain-text tables and JSON for CLI output."""

from __future__ import annotations

import json

import numpy as np


def to_jsonable(value):
    """numpy arrays/scalars -> lists/floats, recursively."""
    if isinstance(value, dict):
        return {k: to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


def print_json(payload: dict) -> None:
    """Print ``payload`` as indented JSON (numpy arrays and scalars converted by ``to_jsonable``)."""
    print(json.dumps(to_jsonable(payload), indent=2))


def format_table(headers: list[str], rows: list[list], floatfmt: str = "{:.9f}") -> str:
    """Left-aligned text table; floats formatted with ``floatfmt``."""
    cells = [[floatfmt.format(c) if isinstance(c, (float, np.floating)) else str(c) for c in row] for row in rows]
    widths = [max(len(h), *(len(r[i]) for r in cells)) for i, h in enumerate(headers)]
    line = "  ".join(h.ljust(w) for h, w in zip(headers, widths))
    out = [line, "  ".join("-" * w for w in widths)]
    out += ["  ".join(c.ljust(w) for c, w in zip(row, widths)) for row in cells]
    return "\n".join(out)
