"""The leg lengths a batch of joint states measures (pure): the strut encoders (leg_*) and, where the
units report (vib_*), each leg's hinge-to-hinge length as sensed (estimation.sensed_lengths: strut plus unit,
the unit carried forward by its sensor's latency). States whose lengths are no measurement of this robot (not
finite, beyond MAX_JOINT_POSITION_M, or fewer positions than names) are dropped with the reason, and so is a
batch whose names lack a leg or repeat one: the kinematics node counts them as malformed input.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import MalformedMessageError
from ..estimation.sensed_lengths import sensed_leg_lengths
from ..robot import LEG_NAMES
from .joint_states import JointStateBatch
from .stamped import MAX_JOINT_POSITION_M, rows_within


@dataclass(frozen=True)
class LegLengths:
    """The usable states of a batch: ``stamps`` [m] (s), ``struts`` [m, 6] (m, the encoders) and ``lengths``
    [m, 6] (m, as sensed); ``kept`` [n] which of the batch's states they are; ``dropped`` why the others
    were, each reason with how many states it dropped."""

    stamps: np.ndarray
    struts: np.ndarray
    lengths: np.ndarray
    kept: np.ndarray
    dropped: tuple[tuple[MalformedMessageError, int], ...]


def leg_lengths(batch: JointStateBatch, legs_at, vib_at, unit_sensor_latency_s: float = 0.0) -> LegLengths:
    """The leg lengths of ``batch``: ``legs_at`` / ``vib_at`` are the columns of leg_1..6 / vib_1..6 in its
    names (index arrays; None where a name is missing or repeats, as nodes.message_conversions.JointColumns
    gives them); the units' readings are carried forward by ``unit_sensor_latency_s`` (s)."""
    count = len(batch.stamps)
    if legs_at is None:
        error = MalformedMessageError(f"joint state names {list(batch.names)[:14]} lack one of {list(LEG_NAMES)} "
                                      "or repeat one", field="name", kind="names")
        none = np.empty((0, 6))
        return LegLengths(batch.stamps[:0], none, none, np.zeros(count, bool), ((error, count),))
    struts = batch.position[:, legs_at]
    units, rates = (None, None) if vib_at is None else (batch.position[:, vib_at], batch.velocity[:, vib_at])
    lengths = sensed_leg_lengths(struts, units, rates, unit_sensor_latency_s)
    kept = rows_within(lengths, MAX_JOINT_POSITION_M)
    dropped = () if kept.all() else ((MalformedMessageError(
        f"leg positions not finite or beyond {MAX_JOINT_POSITION_M:g} m (or fewer positions than names)",
        field="position", kind="not_finite"), int((~kept).sum())),)
    return LegLengths(batch.stamps[kept], struts[kept], lengths[kept], kept, dropped)
