"""Typed outcomes for the suite's answers (stewart_vibration_interfaces/msg/Outcome): from a name of the one
outcome table or from a core error, and back to the name for people and records."""

from __future__ import annotations

from stewart_vibration_interfaces.msg import Outcome

from ..errors import StewartError

CODES = {name: getattr(Outcome, name) for name in dir(Outcome)
         if name.isupper() and not name.startswith("_") and isinstance(getattr(Outcome, name), int)}
NAMES = {code: name for name, code in CODES.items()}


def outcome(name: str, message: str = "") -> Outcome:
    """An Outcome with the code of ``name`` (a constant of Outcome.msg) and ``message``; an unknown name is an
    INTERNAL_ERROR that names it (a defect, never a silent success)."""
    if name not in CODES:
        return Outcome(code=Outcome.INTERNAL_ERROR, message=f"unknown outcome {name!r}: {message}")
    return Outcome(code=CODES[name], message=message)


def outcome_of(exc: StewartError) -> Outcome:
    """The Outcome of a core error: its class's (or a RefusedError's own) outcome and its text."""
    return outcome(exc.outcome, str(exc))


def outcome_name(code: int) -> str:
    """The table's name of ``code`` ("code N" for a code outside the table)."""
    return NAMES.get(code, f"code {code}")
