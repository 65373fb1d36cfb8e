"""Typed outcomes for the suite's answers (stewart_vibration_interfaces/msg/Outcome): from a name of the one
outcome table or from a core error, and back to the name for people and records."""

from __future__ import annotations

from stewart_vibration_interfaces.msg import Outcome

from ..errors import StewartError
from ..messages.outcome_codes import CODES, NAMES, outcome_name

__all__ = ["CODES", "NAMES", "outcome", "outcome_name", "outcome_of"]


def outcome(name: str, message: str = "") -> Outcome:
    """An Outcome with the code of ``name`` (a constant of Outcome.msg) and ``message``; an unknown name is an
    INTERNAL_ERROR that names it (a defect, never a silent success)."""
    if name not in CODES:
        return Outcome(code=Outcome.INTERNAL_ERROR, message=f"unknown outcome {name!r}: {message}")
    return Outcome(code=CODES[name], message=message)


def outcome_of(exc: StewartError) -> Outcome:
    """The Outcome of a core error: its class's (or a RefusedError's own) outcome and its text."""
    return outcome(exc.outcome, str(exc))


def end_goal(goal_handle, name: str) -> None:
    """Set an action goal's final status from its outcome ``name``: succeeded, canceled (a cancel asked for
    it) or aborted."""
    if name == "SUCCEEDED":
        goal_handle.succeed()
    elif name == "CANCELED" and goal_handle.is_cancel_requested:
        goal_handle.canceled()
    else:
        goal_handle.abort()
