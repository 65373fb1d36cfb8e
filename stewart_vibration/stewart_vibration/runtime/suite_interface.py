"""What the scenario's steps need from the running suite (no rclpy): the ``SuiteClient`` protocol (the ROS side is
``nodes.suite_client``), the outcomes of the goals it sends and ``StepFailed``. Times in s (sim s unless said),
poses [x, y, z, roll, pitch, yaw] in m and rad in the base frame.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from ..motion.guard_status import GuardStatus


class StepFailed(RuntimeError):
    """A scenario step did not complete (with the reason)."""


@dataclass(frozen=True)
class VibrationStart:
    """How a vibrate goal began: started (with the plan the planner runs: messages' plan record with t0_s and
    pose) or refused (no plan; the outcome name of the one table and the planner's reason)."""

    outcome: str
    message: str
    plan: dict | None

    @property
    def ok(self) -> bool:
        """Whether the vibration started (its plan came)."""
        return self.plan is not None


@dataclass(frozen=True)
class VibrationEnd:
    """How a vibrate goal ended: its outcome name, the planner's message, the active time (s), the cycles
    delivered (the commanded envelope's), the closed loop's corrections and how far they moved the demands
    (SineController.correction)."""

    outcome: str
    message: str
    active_s: float
    cycles_delivered: float
    loop_corrections: int = 0
    demand_correction: float = 0.0


@dataclass(frozen=True)
class MoveResult:
    """How a move_to_pose goal ended: its outcome name and kinematics' message, the residual error of its pose
    estimate (m, rad), the peak external load measured during it (N, N m) and its duration (s)."""

    outcome: str
    message: str
    position_error_m: float
    angle_error_rad: float
    peak_force_n: float
    peak_moment_nm: float
    duration_s: float


@dataclass(frozen=True)
class IdentificationEnd:
    """How an identification of the vibration units ended: the outcome name, the planner's message, the file
    written ("" if none) and the problems of a rejected one."""

    outcome: str
    message: str
    path: str
    problems: list


class SuiteClient(Protocol):
    """What the steps need from the running suite (``nodes.suite_client.SuiteClient`` over ROS)."""

    clock: float | None  # latest /clock (sim s)
    vibration_status: Any  # latest emulation.vibration_status.VibrationReport, or None
    status_history: list  # (state, since, reason) of every vibration/status state change seen

    def spin_until(self, predicate, timeout: float, what: str) -> None:
        """Spin until ``predicate()``; StepFailed after ``timeout`` (wall s) waiting for ``what``, or if a node died."""

    def wait_sim(self, seconds: float, what: str) -> None:
        """Wait ``seconds`` of sim time; StepFailed if the clock stops or a node dies meanwhile."""

    def send_move(self, pose) -> None:
        """Send kinematics' move_to_pose goal to ``pose`` (6,) [x, y, z, roll, pitch, yaw] (m, rad; base) and wait
        until it was taken (StepFailed if not)."""

    def move_result(self) -> MoveResult | None:
        """The latest move goal's result; None while it runs."""

    def ground_truth(self) -> np.ndarray | None:
        """The latest ground-truth platform pose (6,) (m, rad, base frame); None if not followed or none yet."""

    def pose_estimate(self) -> np.ndarray | None:
        """The controller's latest pose estimate (6,) (kinematics' platform/pose_estimate); None before one."""

    def follow_poses(self, on: bool) -> None:
        """Subscribe to the 500 Hz ground truth and pose estimates (``on``; only while a move settles) or stop."""

    def guard_status(self) -> GuardStatus | None:
        """The latest well-formed kinematics/guard_status (motion.guard_status.GuardStatus); None before one."""

    def start_vibration(self, vibration: dict) -> VibrationStart:
        """Send the planner's vibrate goal of ``vibration`` (every key of VIBRATION_KEYS) and wait until it began
        (its plan) or was refused."""

    def identify_units(self, frequencies_hz, output_path: str, timeout_s: float) -> IdentificationEnd:
        """Run the planner's identification of the vibration units at the current pose and return how it ended."""

    def vibration_result(self) -> VibrationEnd | None:
        """The latest vibrate goal's result; None while it runs."""

    def stop_vibration(self) -> bool:
        """Cancel the latest vibrate goal if it runs (a ramp-out); whether a cancel was sent."""
