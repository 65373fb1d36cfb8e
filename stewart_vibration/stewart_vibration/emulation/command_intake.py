"""What the emulated robot does with a command message around the core's checks (pure Python): why a command
is refused before it is read (the node's lifecycle state, the message's byte size), taking a decoded leg
trajectory or vibration window, and the typed answer to every leg trajectory (legs/trajectory_status).
Times in s of the emulator's clock, lengths in m. A decoded trajectory (``traj``) is a
messages.joint_trajectory.TrajectoryData: start ``stamp`` (s, 0 = now), joint ``names``, ``times`` [n] (s from
the stamp), ``positions`` / ``velocities`` / ``accelerations`` [n, k] (None when no point has them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import RefusedError, StewartError
from ..robot import LEG_NAMES
from .command_size import raw_command_refusal
from .vibration_status import VibrationReport

if TYPE_CHECKING:
    from .emulator import HardwareEmulator


def lifecycle_refusal(configured: bool, active: bool) -> str | None:
    """Why the emulator takes no commands in its lifecycle state, or None (configured and active)."""
    if not configured:
        return "the hardware emulator is unconfigured (lifecycle: configure, then activate)"
    if not active:
        return "the hardware emulator is inactive (lifecycle: activate it)"
    return None


def refuse_unread(lifecycle: str | None, data, kind: str) -> None:
    """Raise the refusal of a serialized command of ``kind`` (command_size.LEG_TRAJECTORY or VIBRATION_WINDOW)
    before it is decoded: ``lifecycle`` (``lifecycle_refusal``) first, then its byte size.

    Raises:
        RefusedError: outcome ROBOT_INACTIVE (lifecycle) or LIMIT_EXCEEDED (too many bytes).
    """
    if lifecycle:
        raise RefusedError("ROBOT_INACTIVE", lifecycle)
    too_big = raw_command_refusal(data, kind)
    if too_big:
        raise RefusedError("LIMIT_EXCEEDED", too_big)


def take_leg_trajectory(emulator: HardwareEmulator, traj, lock) -> float:
    """Run ``traj`` (leg_* absolute strut lengths) on ``emulator``, which takes ``lock`` only around its snapshot
    and its commit; returns the time it ends (s). Raises the core's typed refusal (``command_struts``)."""
    return emulator.command_struts(traj.names, traj.stamp, traj.times, traj.positions, traj.velocities,
                                   traj.accelerations, lock=lock).end


def take_vibration_window(emulator: HardwareEmulator, traj,
                          lock) -> tuple[VibrationReport, StewartError | None]:
    """Splice ``traj`` (vib_* unit displacements) into ``emulator``'s vibration buffer under ``lock``; returns
    the vibration status after it and the typed refusal if the window was refused (None if taken)."""
    try:
        with lock:
            emulator.command_vibration(traj.names, traj.stamp, traj.times, traj.positions, traj.velocities,
                                       traj.accelerations)
            return emulator.status.report, None
    except StewartError as exc:
        with lock:
            return emulator.status.report, exc


def final_leg_positions(names, positions: np.ndarray | None) -> np.ndarray:
    """The last point's strut lengths (6,) in LEG_NAMES order (m); NaN for a leg the trajectory does not name
    or has no column for, and all NaN without points or positions."""
    final = np.full(len(LEG_NAMES), np.nan)
    if positions is None or len(positions) == 0:
        return final
    names = list(names)
    for i, name in enumerate(LEG_NAMES):
        if name in names and names.index(name) < positions.shape[1]:
            final[i] = positions[-1, names.index(name)]
    return final


@dataclass(frozen=True)
class LegTrajectoryAnswer:
    """The answer to one leg trajectory: ``seq`` (1, 2, ... per answer), taken or refused (``error``: the typed
    refusal), its ``points``, when it ends (``end_time_s``, NaN if refused), its ``final_positions`` (6,) m
    and the emulator's time at the answer (``stamp_s``)."""

    seq: int
    points: int
    final_positions: np.ndarray
    stamp_s: float
    end_time_s: float = math.nan
    error: StewartError | None = None

    @property
    def accepted(self) -> bool:
        """Whether the trajectory was taken."""
        return self.error is None


class LegTrajectoryAnswers:
    """Numbers the answers to leg trajectories (from 1, every trajectory gets one, taken or refused)."""

    def __init__(self) -> None:
        self.seq = 0  # the last answer's number

    def answer(self, traj, error: StewartError | None, end_time_s: float,
               stamp_s: float) -> LegTrajectoryAnswer:
        """The answer to ``traj`` (None when it was refused unread), refused with ``error`` or taken to end at
        ``end_time_s`` (s), at the emulator's time ``stamp_s`` (s)."""
        self.seq += 1
        if traj is None:
            return LegTrajectoryAnswer(self.seq, 0, final_leg_positions((), None), stamp_s, end_time_s, error)
        return LegTrajectoryAnswer(self.seq, len(traj.times), final_leg_positions(traj.names, traj.positions),
                                   stamp_s, end_time_s, error)
