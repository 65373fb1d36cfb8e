"""A move goal the planning page sent, followed until the controller's pose estimate settles at its target (pure).

The planning_ui node feeds it the pose estimates it reads and the move goal's feedback and result; the page
sees ``view`` in every frame. Poses [x, y, z, roll, pitch, yaw] in m, rad of the platform frame in the base
frame; stamps s of the estimate's clock (sim time); ``now`` s of the node's monotonic clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..runtime.sim_clock import HeldFor
from . import model
from .suite_status import Event

SETTLE_POSITION_M = 1e-5  # a move is settled when the pose estimate holds within 10 um / 0.01 deg for 0.5 s
SETTLE_ANGLE_RAD = math.radians(0.01)
SETTLE_HOLD_S = 0.5
MOVE_TIMEOUT_S = 120.0  # a move not settled by then no longer blocks a start


@dataclass
class FollowedMove:
    """One move goal: ``target`` pose (m, rad), ``sent`` (monotonic s), its ``status`` ("moving", "settled",
    "ended <OUTCOME>", "not taken") and what its feedback and result said (None until they say it)."""

    target: np.ndarray
    sent: float
    status: str = "moving"
    progress: float | None = None  # 0..1, the goal's latest feedback
    outcome: str | None = None  # the result's outcome name
    peak_force_n: float | None = None
    reason: str | None = None  # why it ended other than settled
    settled_after_s: float | None = None  # monotonic s from sent to settled
    held: HeldFor = field(default_factory=lambda: HeldFor(SETTLE_HOLD_S))

    @property
    def moving(self) -> bool:
        """Sent and neither settled nor ended."""
        return self.status == "moving"

    def blocks_start(self, now: float) -> bool:
        """A vibration must not start while the platform is still on its way (for at most MOVE_TIMEOUT_S)."""
        return self.moving and now - self.sent < MOVE_TIMEOUT_S

    def follow(self, stamps, poses, now: float) -> None:
        """Pose estimates poses [n, 6] at stamps [n] (s): settled once they stay within SETTLE_POSITION_M /
        SETTLE_ANGLE_RAD of the target for SETTLE_HOLD_S of their stamps."""
        if not self.moving:
            return
        for stamp, pose in zip(stamps, poses, strict=True):
            position, angle = model.pose_error(pose, self.target)
            if self.held.update(position < SETTLE_POSITION_M and angle < SETTLE_ANGLE_RAD, stamp):
                self.status, self.settled_after_s = "settled", now - self.sent
                break

    def progressed(self, progress: float) -> None:
        """The goal's feedback: the fraction of the path done (0..1)."""
        self.progress = progress

    def ended(self, result: dict) -> Event | None:
        """The goal's result record (outcome name, message, peak_force_n N; nodes.move_messages.move_result_record):
        the event to log when it ended other than SUCCEEDED."""
        outcome = result["outcome"]
        self.outcome, self.peak_force_n = outcome, result["peak_force_n"]
        if outcome == "SUCCEEDED":
            return None
        self.status, self.reason = f"ended {outcome}", result["message"]
        return Event("kinematics", f"move {outcome}: {result['message']}", "WARN")

    def sent_event(self) -> Event:
        """The event that says the goal was sent, with its target in mm / deg."""
        fields = model.pose_fields(self.target)
        return Event("planning_ui", "move goal sent: " + ", ".join(f"{k} {v:.3f}" for k, v in fields.items()), "OK")

    def not_taken(self) -> None:
        """The kinematics node refused the goal (or it could not be sent)."""
        self.status, self.reason = "not taken", "kinematics did not take the goal"

    def view(self, now: float, estimate) -> dict:
        """The page's view: status, what the goal said, the target in mm / deg, the error of ``estimate`` (the
        latest pose estimate, None if none) in um / deg, and the seconds since it was sent."""
        view: dict = {"target": model.pose_fields(self.target), "status": self.status, "held_since": self.held.since}
        said = {"progress": self.progress, "outcome": self.outcome, "peak_force_n": self.peak_force_n,
                "reason": self.reason, "settled_after_s": self.settled_after_s}
        view.update({key: value for key, value in said.items() if value is not None})  # the page tests presence
        if estimate is not None:
            position, angle = model.pose_error(estimate, self.target)
            view.update(error_um=position * 1e6, error_deg=math.degrees(angle))
        view["elapsed_s"] = now - self.sent
        return view
