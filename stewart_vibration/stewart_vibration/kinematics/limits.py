"""Where the robot's limits are checked: one function per kind of limit, with the typed error it raises.

Every command and pose in the suite is checked here (or by the callers of these functions):

- ``check_stroke``: strut lengths against [stroke_min, stroke_max] (inverse and forward kinematics, the
  vibration's extreme lengths, the emulator's leg trajectories);
- ``check_reachable``: a platform pose's leg vectors -- platform hinges above the base hinges, strokes,
  universal and spherical joint angles;
- ``check_conditioning``: the dimensionally homogeneous condition number of the Jacobian.

The actuators' velocity, acceleration and force limits are checked where those quantities are made
(``emulation.strut_trajectory``, ``vibration.feasibility``, ``motion.paths``).
"""

from __future__ import annotations

import numpy as np

from ..errors import JointLimitError, SingularPoseError, StrokeLimitError, UnreachablePoseError
from ..input_checks import first_violation
from ..robot import Limits
from .geometry import joint_angles_from_axes


def _millimetres_or_micrometres(metres: float) -> str:
    return f"{metres * 1e3:.3f} mm" if metres >= 1e-4 else f"{metres * 1e6:.3f} um"


def check_stroke(low, high, limits: Limits, what: str = "length", suffix: str = "") -> None:
    """Raise StrokeLimitError if a strut's lowest length is below stroke_min or its highest above stroke_max.

    Args:
        low: lowest length of each strut, [..., 6] (m); the flat index of a row is the error's sample.
        high: highest length of each strut, [..., 6] (m); the same array as ``low`` for plain lengths.
        limits: the robot's limits (stroke_min, stroke_max, m).
        what: what the lengths are, for the message ("length", "vibrating length", ...).
        suffix: appended to the message (e.g. why a trajectory was checked from now).

    Raises:
        StrokeLimitError: with ``leg`` (1..6), ``sample`` (flat row index, None for one row), ``value`` and
            ``limit`` (m) of the first violation, below the minimum before above the maximum.
    """
    low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
    for values, mask, limit, word in (
        (low, low < limits.stroke_min, limits.stroke_min, "below the minimum"),
        (high, high > limits.stroke_max, limits.stroke_max, "above the maximum"),
    ):
        if mask.any():
            sample, leg = first_violation(mask)
            value = float(values.reshape(-1, 6)[sample, leg])
            where = f" (sample {sample})" if values.ndim > 1 else ""
            raise StrokeLimitError(
                f"stroke limit{where}: leg {leg + 1} {what} {value:.6f} m is "
                f"{_millimetres_or_micrometres(abs(value - limit))} {word} stroke {limit:.6f} m{suffix}",
                leg=leg + 1,
                sample=sample if values.ndim > 1 else None,
                value=value,
                limit=limit,
            )


def check_reachable(limits: Limits, d: np.ndarray, lengths: np.ndarray, rot: np.ndarray) -> None:
    """Check that a platform pose can be taken: hinges above the base, strokes, joint angles.

    Args:
        limits: the robot's limits.
        d: leg vectors d_i [..., 6, 3] (base frame, m).
        lengths: |d_i| [..., 6] (m).
        rot: platform rotation R [..., 3, 3].

    Raises:
        UnreachablePoseError: a platform hinge is not above the base hinge plane (d_i,z <= 0).
        StrokeLimitError: a leg length is outside the stroke (``check_stroke``).
        JointLimitError: a universal (base) or spherical (platform) joint angle exceeds its limit.
    """
    below = d[..., 2] <= 0.0
    if below.any():
        sample, leg = first_violation(below)
        raise UnreachablePoseError(
            f"unreachable pose (sample {sample}): platform hinge of leg {leg + 1} is not above "
            f"the base hinge plane (d_z = {d.reshape(-1, 6, 3)[sample, leg, 2]:.6g} m)",
            leg=leg + 1,
            sample=sample,
        )
    batch = lengths.reshape(-1, 6)
    check_stroke(batch, batch, limits)
    universal, spherical = joint_angles_from_axes(d / lengths[..., None], rot)
    for angles, limit, name in (
        (universal, limits.universal_joint_max, "universal (base)"),
        (spherical, limits.spherical_joint_max, "spherical (platform)"),
    ):
        mask = angles > limit
        if mask.any():
            sample, leg = first_violation(mask)
            value = float(angles.reshape(-1, 6)[sample, leg])
            raise JointLimitError(
                f"joint limit (sample {sample}): {name} joint of leg {leg + 1} at "
                f"{np.degrees(value):.3f} deg exceeds {np.degrees(limit):.3f} deg by "
                f"{np.degrees(value - limit):.3f} deg",
                leg=leg + 1,
                sample=sample,
                value=value,
                limit=limit,
            )


def check_conditioning(limits: Limits, cond: np.ndarray) -> None:
    """Raise SingularPoseError if a condition number [...] exceeds condition_number_max (or is NaN).

    Args:
        limits: the robot's limits (condition_number_max).
        cond: condition numbers [...] (e.g. from ``condition_number``); the flat index is the error's sample.

    Raises:
        SingularPoseError: with ``sample`` (flat index), ``value`` and ``limit`` of the first violation.
    """
    bad = ~(np.asarray(cond) <= limits.condition_number_max)
    if bad.any():
        sample = int(np.argmax(bad.reshape(-1)))
        value = float(np.asarray(cond).reshape(-1)[sample])
        raise SingularPoseError(
            f"near-singular pose (sample {sample}): condition number {value:.4g} exceeds "
            f"{limits.condition_number_max:.4g}",
            sample=sample,
            value=value,
            limit=limits.condition_number_max,
        )
