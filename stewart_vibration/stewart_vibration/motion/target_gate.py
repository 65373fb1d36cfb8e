"""When the kinematics node takes a new target (pure): the policy against trains of targets.

A target is refused while the move sent last is pending or under way (``ForceGuard.move_under_way``:
from its sending until it is at rest at its end, unless a trip stopped it or it moves nothing), and
beyond ``rate_hz`` targets per second of wall time (a token bucket with bursts of ``rate_hz``, at least
one): a flood of targets -- also moves of nothing, which never block -- cannot flood the emulator with
trajectories. A refused target changes nothing; the sender tries again later.
"""

from __future__ import annotations

from ..rate_limit import RateLimiter
from .force_guard import ForceGuard


class TargetGate:
    """``refusal(sim_now, wall_now)``: why a target is not taken now, or None (then it counts against the rate)."""

    def __init__(self, guard: ForceGuard, rate_hz: float):
        self.guard = guard
        self.rate = RateLimiter(rate_hz, max(float(rate_hz), 1.0))

    def refusal(self, sim_now: float, wall_now: float) -> str | None:
        """The reason a target arriving at ``sim_now`` (s, emulator clock) and ``wall_now`` (s, monotonic) is
        refused, or None: it is taken (and uses one of the rate's tokens)."""
        busy_until = self.guard.move_under_way(sim_now)
        if busy_until is not None:
            return (f"a move is under way until {busy_until:.3f} s (sim time); send the next target once it has "
                    "ended")
        if not self.rate.allow(wall_now):
            return f"more than target_rate_hz {self.rate.rate:g} targets per second; send it again later"
        return None
