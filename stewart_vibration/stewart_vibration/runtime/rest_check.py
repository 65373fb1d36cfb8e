"""When a stopped scenario has left the robot at rest (pure): no vibrate goal open -- a vibration still waiting
for its t0 has idle units, yet would start -- the vibration units idle (or stopped), and the platform's pose
still for a hold time of sim time."""

from __future__ import annotations

from ..vibration.start_gate import UNITS_AT_REST
from .sim_clock import StillFor


class RestCheck:
    """Fed each time the runner looks: ``update`` is True once the robot is at rest (module docstring).

    Args:
        hold_s: how long (s of sim time) the pose must hold still.
    """

    def __init__(self, hold_s: float):
        self.still = StillFor(hold_s)

    def update(self, goal_open: bool, unit_state: str | None, pose, clock: float | None) -> bool:
        """``goal_open``: a vibrate goal was accepted and has no result yet; ``unit_state``: the units' latest
        reported state (None before any report); ``pose`` (6,) m, rad or None: the platform's latest pose;
        ``clock``: sim time (s) or None."""
        if pose is None or clock is None or goal_open or (unit_state is not None and unit_state not in UNITS_AT_REST):
            return False
        return self.still.update(pose, clock)
