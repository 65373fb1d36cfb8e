"""The force guard's settings as the kinematics node's parameters name them (pure): a guard made from them at
start, and a later set of them applied at once (parameters.tables.KINEMATICS checks their ranges before).

guard_force_n (N) and guard_moment_nm (N m): the limits, 0 = off; a changed limit clears a latched trip (the
operator decided). guard_deceleration_scale: the fraction of strut_acceleration_max a stop may use.
guard_max_estimate_age_s (s): how far the newest wrench estimate may lag the newest state before a move pauses.
guard_blind_travel_m (m): how far the struts may move in the estimates' lag (moves slow down to keep to it).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..robot import Robot
from .force_guard import ForceGuard

GUARD_PARAMETERS = ("guard_force_n", "guard_moment_nm", "guard_deceleration_scale", "guard_max_estimate_age_s",
                    "guard_blind_travel_m")


def guard_from_parameters(robot: Robot, values: Mapping[str, float]) -> ForceGuard:
    """A force guard for ``robot`` with the settings of ``values`` (parameter name -> value; every
    GUARD_PARAMETERS name present)."""
    return ForceGuard(robot, values["guard_force_n"], values["guard_moment_nm"], values["guard_deceleration_scale"],
                      values["guard_max_estimate_age_s"], values["guard_blind_travel_m"])


def apply_guard_parameters(guard: ForceGuard, values: Mapping[str, Any]) -> bool | None:
    """Apply the guard's settings among ``values`` (parameter name -> value; other names are ignored). Returns
    None when there is none, else whether a new limit cleared a latched trip."""
    settings = {name: float(value) for name, value in values.items() if name in GUARD_PARAMETERS}
    if not settings:
        return None
    if "guard_blind_travel_m" in settings:
        guard.estimates.blind_travel = settings["guard_blind_travel_m"]
    if "guard_max_estimate_age_s" in settings:
        guard.estimates.max_estimate_age = settings["guard_max_estimate_age_s"]
    if "guard_deceleration_scale" in settings:
        guard.deceleration_scale = settings["guard_deceleration_scale"]
    return guard.set_limits(settings.get("guard_force_n"), settings.get("guard_moment_nm"))
