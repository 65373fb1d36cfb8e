"""A change of the vibration planner's parameters, checked before it takes effect (pure): the settings as they
would be against settings.settings_reason, and a new identification_file read once, here (what it holds is what
the planner plans with next)."""

from __future__ import annotations

from ..errors import StewartError
from ..robot import Robot
from .settings import settings_reason
from .unit_identification import VibrationIdentification, load_identification_option


def parameter_change(robot: Robot, settings: dict, changes: dict) -> tuple[str, tuple[str, VibrationIdentification
                                                                                       | None] | None]:
    """Why ``changes`` ({name: value}) to the planner's ``settings`` are refused ("" when they are taken), and a
    changed identification_file's (path, identification; None for '') as read (None when it is not changed or
    the change is refused)."""
    changed = dict(settings)
    changed.update({name: value for name, value in changes.items() if name in changed})
    try:
        reason = settings_reason(robot, changed) or ""
    except (TypeError, ValueError) as exc:
        reason = f"invalid parameter value: {exc}"
    if reason or "identification_file" not in changes:
        return reason, None
    path = changes["identification_file"]
    try:
        return "", (path, load_identification_option(path))
    except StewartError as exc:
        return f"identification_file: {exc}", None
