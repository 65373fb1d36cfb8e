"""Typed values of a parsed config file, each checked against a plausible range (pure python).

Every config reader of the package (robot, tissue, simulation, scenario) takes its values through these,
so a wrong type, a missing key, a non-finite number or one outside its plausible range is one ConfigError
line that names the file and the key: ``robot config config/robot.yaml: 'limits.stroke_max_m' = 1000 is
outside its plausible range [0.01, 2] m``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import ConfigError
from .safe_yaml import short_repr


@dataclass(frozen=True)
class Plausible:
    """A plausible range [low, high] (``low_open``: low itself excluded) in ``unit``."""

    low: float
    high: float
    unit: str = ""
    low_open: bool = False

    def __contains__(self, value: float) -> bool:
        return (self.low < value if self.low_open else self.low <= value) and value <= self.high

    def __str__(self) -> str:
        unit = f" {self.unit}" if self.unit else ""
        return f"{'(' if self.low_open else '['}{self.low:g}, {self.high:g}]{unit}"


def lookup(tree, dotted: str, where: str):
    """The value at ``dotted`` ("limits.stroke_max_m") in nested mappings; ConfigError naming it if missing."""
    node = tree
    for key in dotted.split("."):
        if not isinstance(node, dict) or key not in node:
            raise ConfigError(f"{where}: missing field '{dotted}'")
        node = node[key]
    return node


def as_number(value, key: str, where: str, plausible: Plausible | None = None, integer: bool = False) -> float:
    """``value`` as a finite float (a whole number with ``integer``) inside ``plausible``.

    Args:
        value: the parsed value: an int or float, or a string float() reads (PyYAML reads ``1e-4``,
            without a dot, as a string); not a bool.
        key: the key's name, for the message.
        where: the file ("robot config config/robot.yaml"), for the message.
        plausible: the range the value must lie in (None: any finite number).
        integer: the value must be a whole number.

    Returns:
        The number (float; a whole number when ``integer``).

    Raises:
        ConfigError: naming ``key``: not a number, not finite, not whole, or outside ``plausible``.
    """
    number = None
    if isinstance(value, (int, float, str)) and not isinstance(value, bool):
        try:
            number = float(value)
        except (ValueError, OverflowError):  # a huge int overflows float
            number = None
    if number is None:
        raise ConfigError(f"{where}: '{key}' must be a number, got {short_repr(value)}")
    if not math.isfinite(number):
        raise ConfigError(f"{where}: '{key}' must be finite, got {short_repr(value)}")
    if integer and number != int(number):
        raise ConfigError(f"{where}: '{key}' must be a whole number, got {short_repr(value)}")
    if plausible is not None and number not in plausible:
        raise ConfigError(f"{where}: '{key}' = {number:g} is outside its plausible range {plausible}")
    return number


def as_vector(value, key: str, where: str, length: int, plausible: Plausible | None = None) -> np.ndarray:
    """``value`` as a (length,) float array of finite numbers, each inside ``plausible``.

    Raises:
        ConfigError: naming ``key`` (and the entry): not a list of ``length`` numbers, or an entry that
            ``as_number`` refuses.
    """
    if not isinstance(value, list) or len(value) != length:
        raise ConfigError(f"{where}: '{key}' must be a list of {length} numbers, got {short_repr(value)}")
    return np.array([as_number(v, f"{key}[{i}]", where, plausible) for i, v in enumerate(value)])


def as_choice(value, key: str, where: str, choices) -> str:
    """``value`` if it is one of the strings ``choices``; ConfigError naming ``key`` and the choices."""
    if not isinstance(value, str) or value not in choices:
        raise ConfigError(f"{where}: '{key}' must be one of {list(choices)}, got {short_repr(value)}")
    return value


def check_keys(tree: dict, allowed, where: str, prefix: str = "") -> None:
    """ConfigError naming the keys of the mapping ``tree`` that are not in ``allowed`` (a typo is never
    silently ignored); ``prefix`` is the mapping's own dotted key."""
    unknown = sorted(str(k) for k in tree if k not in allowed)
    if unknown:
        inside = f" in '{prefix}'" if prefix else ""
        raise ConfigError(f"{where}: unknown keys{inside} {short_repr(unknown)} (known: {sorted(allowed)})")
