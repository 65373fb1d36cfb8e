"""Inverse dynamics of the 6-UPS platform: axial leg forces by Newton-Euler (docs/dynamics.md).

Full model: platform + payload (one rigid body), cylinder and piston mass and
transverse inertia, gravity, Coriolis and centripetal terms, optional external
wrench (soft tissue) and optional strut friction. Batched over any leading
dimensions, no Python loops over samples; large batches are split over
the cores (parallel.map_row_ranges).

Conventions (base frame, SI units): pose [..., 6] = [x, y, z, roll, pitch,
yaw]; twist [..., 6] = [v, w] (velocity of the platform-frame origin, angular
velocity); accel [..., 6] = [a, alpha] (acceleration of the same origin,
angular acceleration). Euler-angle rates convert with
``stewart_vibration.dynamics.platform_trajectory.twist_from_euler_rates``. An external wrench
[..., 6] = [F_E, M_E] acts on the platform: force (N) and moment (N m) about
the platform-frame origin. A positive axial force F_i pushes the platform
away from the base (extends the strut).

Vibration unit: its moving mass is lumped into the piston (rigidly, at the
piston's centre of mass). The unit's stroke is <= 100 um, so the relative
motion of its 30 g changes the leg inertia negligibly; what moves the
platform is the leg length change it produces. The unit and the strut act in
series along the leg, so the axial force computed here is the force of both.
The generated MuJoCo model makes the same choice (``Robot.leg_bodies``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np

from ..input_checks import as_batch
from ..kinematics.legs import cross_first_axis, dot_first_axis, flat_inputs, hinge_motion, leg_axes, leg_motion_soa
from ..kinematics.rotations import rotation_from_rpy
from ..parallel import map_row_ranges
from ..robot import LegBodies, Robot, derived

CHUNK = 8192  # samples per block: fastest measured here (2048: 0.9 M/s, 8192: 1.6 M/s, 16384: 0.7 M/s)


@dataclass(frozen=True)
class Friction:
    """Strut friction, per leg or scalar: F_fric = -(coulomb sign(l_dot) + viscous l_dot).

    coulomb (N), viscous (N s/m). The motor must supply the friction on top of
    the frictionless force. Off unless passed to ``leg_forces``.
    """

    coulomb: float | np.ndarray = 0.0
    viscous: float | np.ndarray = 0.0


@dataclass(frozen=True)
class LegForceResult:
    """leg_forces output with reactions, base frame, N.

    force [..., 6]: axial actuator forces; platform_joint [..., 6, 3]: force of
    leg i on the platform at A_i; base_joint [..., 6, 3]: force of the base on
    leg i at B_i; transverse [..., 6, 3]: the part of platform_joint normal to
    the leg.
    """

    force: np.ndarray
    platform_joint: np.ndarray
    base_joint: np.ndarray
    transverse: np.ndarray


def _platform_terms(robot: Robot, rot_t, arm, twist, accel, wrench):
    """Arms rho_i [3, 6, n] from the COM, and the platform's required force and moment about
    the COM [3, n] (minus the external wrench). rot_t: R as [3, 3, n]; twist, accel, wrench: [6, n]."""
    body = robot.moving_body
    c = (rot_t * body.com[None, :, None]).sum(axis=1)  # COM offset from the platform origin
    w, alpha, a = twist[3:], accel[3:], accel[:3]
    a_c = a + cross_first_axis(alpha, c) + cross_first_axis(w, cross_first_axis(w, c))

    def world_inertia_times(x):  # R I R^T x, component-wise
        local = body.inertia @ (rot_t * x[:, None, :]).sum(axis=0)
        return (rot_t * local[None, :, :]).sum(axis=1)

    f_ext, m_ext = wrench[:3], wrench[3:]
    force = body.mass * (a_c - robot.gravity[:, None]) - f_ext
    moment = (world_inertia_times(alpha) + cross_first_axis(w, world_inertia_times(w))
              - (m_ext - cross_first_axis(c, f_ext)))
    rho = arm - c[:, None, :]
    return rho, force, moment


def _preconditioner(robot: Robot) -> np.ndarray:
    """H0^-1 (6, 6): inverse of H at the home pose at rest (cached per robot)."""

    def build() -> np.ndarray:
        home = robot.home_pose
        rot = rotation_from_rpy(home[3:])
        arm = robot.platform_hinges @ rot.T
        d = home[:3] + arm - robot.base_hinges
        s = d / np.linalg.norm(d, axis=1, keepdims=True)
        rho = arm - rot @ robot.moving_body.com
        return np.linalg.inv(np.concatenate([s, np.cross(rho, s)], axis=1).T)

    return derived(robot, "dynamics_preconditioner", build)


def _eliminate(g: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Gaussian elimination without pivoting, in place, on g [6, 6, n] (row, column, sample), b [6, n]."""
    for k in range(5):
        f = g[k + 1:, k] / g[k, k]
        g[k + 1:, k + 1:] -= f[:, None, :] * g[k, None, k + 1:]
        b[k + 1:] -= f * b[k]
    x = np.empty_like(b)
    for k in range(5, -1, -1):
        x[k] = (b[k] - (g[k, k + 1:] * x[k + 1:]).sum(axis=0)) / g[k, k]
    return x


def _solve(robot: Robot, axis, rho, h, force, moment):
    """Solve H F = [force - sum h; moment - sum rho x h], H columns [s_i; rho_i x s_i] -> F [6, n].

    axis, rho, h: [3, 6, n]; force, moment: [3, n]. Batched 6x6 solves: the
    system is preconditioned with the home-pose inverse H0^-1 (so it is close
    to the identity in the workspace) and eliminated without pivoting over all
    samples at once; every solution is checked by its residual in the
    original system, and samples that fail (far from home, near-singular)
    are re-solved with LAPACK (partial pivoting).
    """
    n = axis.shape[-1]
    hmat = np.empty((6, 6, n))  # [row, leg, sample]
    hmat[:3] = axis
    hmat[3:] = cross_first_axis(rho, axis)
    rhs = np.empty((6, n))
    rhs[:3] = force - h.sum(axis=1)
    rhs[3:] = moment - cross_first_axis(rho, h).sum(axis=1)
    pre = _preconditioner(robot)
    g = (pre @ hmat.reshape(6, -1)).reshape(6, 6, n)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        x = _eliminate(g, pre @ rhs)
        prod = hmat * x[None]
        residual = np.abs(prod.sum(axis=1) - rhs)
        scale = np.abs(prod).sum(axis=1) + np.abs(rhs)
        bad = ~(residual <= 1e-12 * scale + 1e-300).all(axis=0)
    if bad.any():
        idx = np.flatnonzero(bad)
        x[:, idx] = np.linalg.solve(hmat[:, :, idx].transpose(2, 0, 1), rhs[:, idx].T[..., None])[..., 0].T
    return x


def _full_block(robot: Robot, p: LegBodies, pose, twist, accel, wrench, reactions: bool):
    """Steps 1-8 for one block (inputs [6, n], vectors [3, 6, n]); leg terms in closed form.

    With w_i = s x v_A / l and alpha_i = (s x a_A - 2 l_dot w_i) / l (steps 3-4),
    the leg's moment about B_i (step 6) is
    M_i = I_eff alpha_i + 2 m2 (l - e2) l_dot w_i - mu s x g, with
    I_eff = I_t1 + I_t2 + m1 e1^2 + m2 (l - e2)^2 and mu = m1 e1 + m2 (l - e2);
    so f_perp = (s x M_i) / l = -k_a a_A_perp + k_v v_A_perp + k_g g_perp with
    k_a = I_eff / l^2, k_v = 2 l_dot (I_eff / l - m2 (l - e2)) / l^2, k_g = mu / l,
    and s.a2 = s.a_A + e2 |v_A_perp|^2 / l^2 (x_perp = x - (s.x) s).
    """
    n = pose.shape[-1]
    # the notation of docs/dynamics.md: cylinder m1, e1, I_t1; piston (with the vibration unit) m2, e2, I_t2
    m1, e1, it1 = p.cylinder_mass, p.cylinder_com_offset, p.cylinder_inertia_transverse
    m2, e2, it2 = p.piston_mass, p.piston_com_offset, p.piston_inertia_transverse
    rot_t, r, length, inv_l, s = leg_axes(robot, pose)
    v_a, a_a = hinge_motion(r, twist, accel)
    g = robot.gravity
    l_dot, s_a, s_g = dot_first_axis(s, v_a), dot_first_axis(s, a_a), s[0] * g[0] + s[1] * g[1] + s[2] * g[2]
    v_perp2 = (dot_first_axis(v_a, v_a) - l_dot * l_dot) * inv_l * inv_l
    arm2 = length - e2
    inv_l2 = inv_l * inv_l
    i_eff = (it1 + it2 + m1 * e1 * e1) + m2 * arm2 * arm2
    k_a = i_eff * inv_l2
    k_v = 2.0 * l_dot * (i_eff * inv_l - m2 * arm2) * inv_l2
    k_g = (m1 * e1 + m2 * arm2) * inv_l
    # Step 7: h_i = m2 s.(g - a2) s + f_perp (leg-on-platform force minus F_i s).
    coef = k_a * s_a - k_v * l_dot - k_g * s_g + m2 * (s_g - s_a - e2 * v_perp2)
    h = np.empty((3, 6, n))
    for k in range(3):
        h[k] = k_v * v_a[k] - k_a * a_a[k] + coef * s[k] + k_g * g[k]
    # Step 8: platform Newton-Euler about its centre of mass.
    rho, force, mom = _platform_terms(robot, rot_t, r, twist, accel, wrench)
    axial = _solve(robot, s, rho, h, force, mom)
    if not reactions:
        return axial, l_dot, None
    l_ddot = s_a + length * v_perp2
    s_ddot = (a_a - l_ddot * s - 2.0 * l_dot * inv_l * (v_a - l_dot * s)) * inv_l
    a1 = e1 * s_ddot
    a2 = a_a - e2 * s_ddot  # piston COM = A_i - e2 s
    transverse = h - (m2 * (s_g - dot_first_axis(s, a2))) * s
    platform_joint = axial * s + h
    gg = g[:, None, None]  # [3, 1, 1]
    base_joint = m1 * (a1 - gg) + m2 * (a2 - gg) + platform_joint
    return axial, l_dot, (platform_joint, base_joint, transverse)


def _paper_block(robot: Robot, p: LegBodies, pose, twist, accel, wrench, reactions: bool):
    m = leg_motion_soa(robot, pose, twist, accel)
    s = m.axis
    h = -(p.piston_mass * dot_first_axis(s, m.hinge_accel - robot.gravity[:, None, None])) * s
    rho, force, mom = _platform_terms(robot, m.rotation, m.arm, twist, accel, wrench)
    return _solve(robot, s, rho, h, force, mom), m.length_rate, None


def _run_blocks(block, robot: Robot, pose, twist, accel, external_wrench, reactions: bool):
    batch, pose, twist, accel = flat_inputs(pose, twist, accel)  # [6, n]
    n = pose.shape[-1]
    if external_wrench is None:
        wrench = np.zeros((6, n))
    else:
        wrench = as_batch(external_wrench, 6, "external_wrench")
        wrench = np.ascontiguousarray(np.broadcast_to(wrench, batch + (6,)).reshape(-1, 6).T)
    p = robot.leg_bodies
    force, rate = np.empty((6, n)), np.empty((6, n))
    extra = [np.empty((3, 6, n)) for _ in range(3)] if reactions else None

    def run(first: int, stop: int) -> None:
        for i in range(first, stop, CHUNK):
            sl = slice(i, min(i + CHUNK, stop))
            force[:, sl], rate[:, sl], parts = block(robot, p, pose[:, sl], twist[:, sl], accel[:, sl],
                                                     wrench[:, sl], reactions)
            if reactions:
                for dst, src in zip(cast(list[np.ndarray], extra), parts):  # a list when reactions
                    dst[..., sl] = src

    map_row_ranges(run, n, min_rows=8 * CHUNK, align=CHUNK)  # blocks split over the cores
    return batch, force.T, rate.T, extra


def leg_forces(robot: Robot, pose, twist, accel, external_wrench=None, friction: Friction | None = None,
               return_reactions: bool = False):
    """Axial actuator forces [..., 6] (N) for a platform motion, full Newton-Euler model.

    Args:
        robot: the robot (platform + payload body, leg bodies, gravity).
        pose: platform poses [..., 6] = [x, y, z, roll, pitch, yaw] (m, rad).
        twist: platform twists [..., 6] = [v, w] of the platform origin (m/s, rad/s; base frame).
        accel: platform accelerations [..., 6] = [a, alpha] of the same point (m/s^2, rad/s^2; base frame).
        external_wrench: optional wrench on the platform [..., 6] = [F_E, M_E] (N, N m about the platform
            origin; base frame), broadcast to the batch shape of the motion; None = no external load.
        friction: optional Friction (motor force = frictionless force + coulomb sign(l_dot) + viscous l_dot,
            coulomb and viscous scalars or per leg (6,)).
        return_reactions: also return the joint reactions.

    Returns:
        Axial forces [..., 6] (N, positive extends the strut), the batch shape that of pose, twist and accel
        broadcast together; with ``return_reactions`` a LegForceResult whose ``force`` is that array and whose
        platform_joint, base_joint and transverse [..., 6, 3] (N, base frame) are the frictionless reactions.

    Raises:
        InvalidInputError: pose, twist, accel or external_wrench is not numeric, not [..., 6] or not finite
            (``as_batch``).
        ValueError: the batch shapes of pose, twist and accel do not broadcast, or external_wrench does not
            broadcast to theirs (numpy).
        numpy.linalg.LinAlgError: the 6x6 leg-force system H is exactly singular at a sample whose
            preconditioned solve failed its residual check (the LAPACK fallback).
    """
    batch, force, rate, extra = _run_blocks(_full_block, robot, pose, twist, accel, external_wrench,
                                            return_reactions)
    if friction is not None:
        force = force + np.asarray(friction.coulomb) * np.sign(rate) + np.asarray(friction.viscous) * rate
    force = force.reshape(batch + (6,))
    if not return_reactions:
        return force
    vecs = [x.transpose(2, 1, 0).reshape(batch + (6, 3)) for x in extra]
    return LegForceResult(force, *vecs)


def leg_forces_paper(robot: Robot, pose, twist, accel, external_wrench=None) -> np.ndarray:
    """The paper's simplified model (eqs 12-20), for comparison only: axial forces [..., 6] (N).

    Kept as in the paper: only the piston (mass m_u, here with the vibration
    unit) is modelled, and only its axial inertia and gravity along the leg,
    m_u s_i.(a_ui - g) with a_ui the acceleration of A_i; cylinder mass, leg
    rotational inertia, transverse joint forces, Coriolis and centripetal leg
    terms are dropped. Fixed where the paper cannot be evaluated as printed:
    eq. 19 row 1 takes eq. 14's sign; eq. 20 uses the arms R a_i, and moments
    are taken about the platform's centre of mass (eq. 16 is Euler's equation
    about the COM; the paper's COM is at the platform origin); vector leg
    terms are m_u s_i.(a_ui - g) s_i.

    Args:
        robot: the robot.
        pose: platform poses [..., 6] (m, rad).
        twist: platform twists [..., 6] = [v, w] of the platform origin (m/s, rad/s; base frame).
        accel: platform accelerations [..., 6] = [a, alpha] (m/s^2, rad/s^2; base frame).
        external_wrench: optional wrench on the platform [..., 6] = [F_E, M_E] (N, N m about the platform
            origin; base frame); None = no external load.

    Returns:
        Axial forces [..., 6] (N, positive extends the strut), the broadcast batch shape of the motion.

    Raises:
        InvalidInputError: pose, twist, accel or external_wrench is not numeric, not [..., 6] or not finite
            (``as_batch``).
        ValueError: the batch shapes of pose, twist and accel do not broadcast, or external_wrench does not
            broadcast to theirs (numpy).
        numpy.linalg.LinAlgError: the 6x6 leg-force system is exactly singular at a sample whose
            preconditioned solve failed its residual check (the LAPACK fallback).
    """
    batch, force, _, _ = _run_blocks(_paper_block, robot, pose, twist, accel, external_wrench, False)
    return force.reshape(batch + (6,))
