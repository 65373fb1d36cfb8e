"""Checked raw PoseStamped and WrenchStamped messages (pure; numpy): the decoders of messages.stamped_doubles
plus what a reader needs to trust them -- frame ``base`` (or empty), finite values, a unit quaternion.

A batch keeps the messages that pass and hands back the errors of the others (``MalformedMessageError``),
so one bad message costs only itself. The checks run on the stacked batch (one numpy pass), not per
message: the 500 Hz streams pay nothing per sample beyond their decoding.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import MalformedMessageError
from ..kinematics.rotations import rpy_from_quaternion
from .fields import BASE_FRAME, check_frame
from .stamped_doubles import decode_stamped_doubles

_FRAMES = {"", BASE_FRAME}
MAX_POSITION_M = 1000.0  # a pose further than 1 km from the base origin is no pose of this robot
MAX_JOINT_POSITION_M = 10.0  # a measured strut or unit length beyond 10 m is no measurement of this robot
MAX_JOINT_SPEED_M_S = 100.0  # nor a strut or unit speed beyond 100 m/s


@dataclass(frozen=True)
class StampedBatch:
    """The well-formed messages of a batch: stamps [m] (s), values [m, k], kept [m] (their indices in the
    batch, in order) and the errors of the others."""

    stamps: np.ndarray
    values: np.ndarray
    kept: np.ndarray
    errors: list


def _batch(messages, count: int, what: str) -> StampedBatch:
    stamps, frames, values, kept, failed = decode_stamped_doubles(messages, count, what)
    errors = [MalformedMessageError(f"{what}: {exc}") for exc in failed]
    good = np.isfinite(values).all(axis=1)
    if not good.all():
        errors.append(MalformedMessageError(f"{what}: {int((~good).sum())} message(s) with non-finite values",
                                            field="values", kind="not_finite"))
    if not set(frames) <= _FRAMES:  # rare: find which (the common case is one set operation per batch)
        for j, frame in enumerate(frames):
            try:
                check_frame(frame, what)
            except MalformedMessageError as exc:
                good[j] = False
                errors.append(exc)
    return StampedBatch(stamps[good], values[good], kept[good], errors)


def rows_within(values, bound: float) -> np.ndarray:
    """[n] bool: which rows of ``values`` [n, k] are finite and within +-``bound`` (e.g. MAX_JOINT_POSITION_M for
    a batch of joint states' positions): one numpy pass."""
    return np.asarray((np.abs(np.asarray(values, float)) <= bound).all(axis=1))  # NaN compares False too


def wrenches_from_cdr(messages, what: str = "WrenchStamped") -> StampedBatch:
    """Checked raw WrenchStamped messages: values [m, 6] = [force (N), torque (N m)] in base."""
    return _batch(messages, 6, what)


def poses_from_cdr(messages, what: str = "PoseStamped", unit_tolerance: float = 1e-6,
                   as_quaternion: bool = False) -> StampedBatch:
    """Checked raw PoseStamped messages: values [m, 6] = poses [x, y, z, roll, pitch, yaw] (m, rad) in base,
    or with ``as_quaternion`` [m, 7] = position (m) and the normalised quaternion [x, y, z, w]; a quaternion
    whose norm is off 1 by more than ``unit_tolerance``, or a position beyond MAX_POSITION_M, is an error."""
    batch = _batch(messages, 7, what)
    if not len(batch.kept):
        return StampedBatch(batch.stamps, np.empty((0, 6)), batch.kept, batch.errors)
    values = batch.values
    norm = np.linalg.norm(values[:, 3:], axis=1)
    unit = np.abs(norm - 1.0) <= unit_tolerance
    errors = list(batch.errors)
    if not unit.all():
        errors.append(MalformedMessageError(
            f"{what}: {int((~unit).sum())} orientation(s) not a unit quaternion (norm {norm[~unit][0]:.6g}, more "
            f"than {unit_tolerance:g} off 1)", field="orientation", kind="range"))
    near = np.abs(values[:, :3]).max(axis=1) <= MAX_POSITION_M
    if not near.all():
        errors.append(MalformedMessageError(f"{what}: {int((~near).sum())} position(s) beyond {MAX_POSITION_M:g} m",
                                            field="position", kind="range"))
    unit &= near
    values = values[unit]
    if as_quaternion:
        values[:, 3:] /= norm[unit][:, None]
        return StampedBatch(batch.stamps[unit], values, batch.kept[unit], errors)
    poses = np.concatenate([values[:, :3], rpy_from_quaternion(values[:, 3:], unit_tolerance=unit_tolerance)],
                           axis=1) if len(values) else np.empty((0, 6))
    return StampedBatch(batch.stamps[unit], poses, batch.kept[unit], errors)


def pose_from_cdr(data, what: str = "PoseStamped", unit_tolerance: float = 1e-6) -> tuple[float, np.ndarray]:
    """(stamp s, pose (6,) m, rad) of one checked raw PoseStamped; MalformedMessageError if it does not pass."""
    batch = poses_from_cdr([data], what, unit_tolerance)
    if batch.errors:
        raise batch.errors[0]
    return float(batch.stamps[0]), batch.values[0]
