"""Platform motion from leg-space measurements and commands, for the leg-force estimator (pure numpy).

Leg space is the total hinge-to-hinge length L_i = strut (leg_i) + vibration
unit (vib_i). With the Jacobian J (rows [n_i, (R a_i) x n_i], base frame):

- twist  t = [v, w] = J^-1 L_dot           (velocity of the platform origin);
- accel  a = [a, alpha] = J^-1 (L_ddot - c), c_i = the velocity-product part of
  L_ddot_i = s_i . (w x (w x r_i)) + |v_A,perp|^2 / l_i, i.e. L_ddot at zero
  acceleration (``kinematics.legs.leg_motion``), which is the J_dot t term.

Commanded leg accelerations come from the commands the emulator follows, with the
emulator's own models: ``emulation.vibration_buffer.VibrationBuffer`` for the vib_*
windows and ``emulation.strut_trajectory.TrajectoryFollower`` for leg_* trajectories.

External wrench: leg_forces is affine in the external wrench W = [F_E, M_E]
(acting on the platform, moment about the platform origin, base frame) with
J^T dF = -W, so from measured and modelled (W = 0) axial forces
W = -J^T (F_measured - F_model). J^T (F_measured - F_model) itself is the
extra wrench the legs exert on the platform.
"""

from __future__ import annotations

import numpy as np

from ..errors import SingularPoseError
from ..input_checks import as_batch
from ..kinematics import jacobian
from ..kinematics.legs import leg_motion


def _solve(jac: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.solve(jac, rhs[..., None])[..., 0]
    except np.linalg.LinAlgError as exc:
        raise SingularPoseError("singular Jacobian: platform motion is not determined by the leg rates") from exc


def platform_twist(robot, pose, length_rate, jac=None) -> np.ndarray:
    """Twist [..., 6] = [v, w] (m/s, rad/s, base frame) from hinge-length rates L_dot [..., 6] (m/s).

    Solves J t = L_dot.

    Args:
        robot: the robot.
        pose: platform poses [..., 6] (m, rad).
        length_rate: hinge-to-hinge length rates L_dot [..., 6] (m/s).
        jac: the Jacobian [..., 6, 6] at ``pose`` if already computed.

    Returns:
        Twists [..., 6] = [v, w] of the platform origin (m/s, rad/s; base frame).

    Raises:
        InvalidInputError: ``pose`` or ``length_rate`` is not numeric, not [..., 6] or not finite.
        SingularPoseError: a Jacobian is singular.
    """
    pose = as_batch(pose, 6, "pose")
    rate = as_batch(length_rate, 6, "length_rate")
    return _solve(jacobian(robot, pose) if jac is None else jac, rate)


def platform_accel(robot, pose, twist, length_accel, jac=None) -> np.ndarray:
    """Acceleration [..., 6] = [a, alpha] of the platform origin from L_ddot [..., 6] (m/s^2) and the twist.

    Solves J a = L_ddot - c with c the velocity-product part of L_ddot (``leg_motion`` at zero acceleration).

    Args:
        robot: the robot.
        pose: platform poses [..., 6] (m, rad).
        twist: platform twists [..., 6] = [v, w] (m/s, rad/s; base frame).
        length_accel: hinge-to-hinge length accelerations L_ddot [..., 6] (m/s^2).
        jac: the Jacobian [..., 6, 6] at ``pose`` if already computed.

    Returns:
        Accelerations [..., 6] = [a, alpha] of the platform origin (m/s^2, rad/s^2; base frame).

    Raises:
        InvalidInputError: ``pose``, ``twist`` or ``length_accel`` is not numeric, not [..., 6] or not finite.
        ValueError: the batch shapes of ``pose`` and ``twist`` do not broadcast (numpy).
        SingularPoseError: a Jacobian is singular.
    """
    pose = as_batch(pose, 6, "pose")
    twist = as_batch(twist, 6, "twist")
    acc = as_batch(length_accel, 6, "length_accel")
    velocity_part = leg_motion(robot, pose, twist, np.zeros_like(twist)).length_accel
    return _solve(jacobian(robot, pose) if jac is None else jac, acc - velocity_part)


def external_wrench(robot, pose, measured, model, jac=None) -> np.ndarray:
    """External wrench on the platform [..., 6] = -J^T (F_measured - F_model) (N, N m about the platform origin).

    Args:
        robot: the robot.
        pose: platform poses [..., 6] (m, rad); not used (nor validated) when ``jac`` is given.
        measured: measured axial forces [..., 6] (N).
        model: modelled axial forces [..., 6] (N) at zero external wrench.
        jac: the Jacobian [..., 6, 6] at ``pose`` if already computed.

    Returns:
        W = [F_E, M_E] [..., 6] (N, N m about the platform origin; base frame).

    Raises:
        InvalidInputError: ``pose`` (without ``jac``), ``measured`` or ``model`` is not numeric, not [..., 6] or
            not finite.
    """
    jac = jacobian(robot, as_batch(pose, 6, "pose")) if jac is None else jac
    diff = as_batch(measured, 6, "measured") - as_batch(model, 6, "model")
    return -np.einsum("...ij,...i->...j", jac, diff)


__all__ = [
    "external_wrench",
    "platform_accel",
    "platform_twist",
]
