"""The pose limits at the checked samples of a strut path and their margins: hinge height d_z (m), universal
and spherical joint angles (rad) and the Jacobian's condition number, with how far each can move while the
struts change by up to a given length (m) -- exact first-order sensitivities plus a second-order allowance --
and the typed error of the tightest limit. Poses in m, rad, base frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import JointLimitError, SingularPoseError, UnreachablePoseError
from ..robot import Robot
from .geometry import cross, joint_angles_from_axes, leg_vectors_from_rotation
from .jacobian import condition_number, jacobian_from_vectors
from .rotations import rotation_from_rpy, rpy_from_rotation, so3_exp

COND_EXACT_ABOVE = 0.2  # above this fraction of condition_number_max its margin comes from measured derivatives
COND_STEP_M = 1e-6  # strut step of those central differences (m)
MARGIN_SAFETY = 1.1  # on the exact first-order changes (the second-order allowance comes on top)


@dataclass
class PoseState:
    """Pose quantities at samples [n] with what the margins need: the joint angles' and d_z's exact first-order
    sensitivities to the strut lengths (``gradients``) and the Jacobian's singular values."""

    d: np.ndarray  # leg vectors [n, 6, 3]
    length: np.ndarray  # [n, 6]
    universal: np.ndarray  # [n, 6] rad
    spherical: np.ndarray  # [n, 6] rad
    condition: np.ndarray  # [n]
    sigma: np.ndarray  # singular values of J_h [n, 6], descending
    poses: np.ndarray
    sensitivity: np.ndarray  # [n, 3, 6]: sum over struts of |d q / d l_j| for q = d_z, universal, spherical (per leg)
    cond_terms: np.ndarray  # [n, 2]: sum over struts of |d cond / d l_j| and |d2 cond / d l_j^2| (NaN: not computed)

    @classmethod
    def at(cls, robot: Robot, poses: np.ndarray) -> PoseState:
        """The quantities at poses [n, 6] (m, rad, base frame)."""
        rot = rotation_from_rpy(poses[:, 3:])
        d, r = leg_vectors_from_rotation(robot, poses[:, :3], rot)
        length = np.sqrt(np.einsum("nij,nij->ni", d, d))
        axes = d / length[..., None]
        universal, spherical = joint_angles_from_axes(axes, rot)
        jac = jacobian_from_vectors(d, r, length)
        sigma = np.linalg.svd(jac * np.r_[1.0, 1.0, 1.0, [1.0 / robot.characteristic_length] * 3], compute_uv=False)
        with np.errstate(divide="ignore"):
            condition = sigma[:, 0] / sigma[:, -1]
        return cls(d, length, universal, spherical, condition, sigma, poses,
                   _sensitivity(jac, r, axes, length, rot, universal, spherical),
                   _condition_terms(robot, poses, rot, jac, condition))

    def margins(self, robot: Robot, half):
        """How far d_z [n, 6] (m), the joint angles [n, 6] (rad) and the condition number [n] can move while every
        strut changes by at most ``half`` [n] (m): MARGIN_SAFETY times the exact first-order change (the
        sensitivities' row sums times ``half``) plus a second-order allowance (the Lipschitz bound below,
        squared, in the quantity's unit); for the condition number Weyl's bound on the singular values, or
        where it is above COND_EXACT_ABOVE of its limit its measured first and second derivatives."""
        arm = float(np.linalg.norm(robot.platform_hinges, axis=1).max())
        scale = robot.characteristic_length
        with np.errstate(divide="ignore", invalid="ignore"):
            pose_h = np.sqrt(6.0) * half / self.sigma[:, -1]  # |(dp, L dphi)|_2
            hinge = np.sqrt(1.0 + (arm / scale) ** 2) * pose_h  # |d d_i|
            turn = pose_h / scale  # |d phi|
            axis = hinge[:, None] / self.length  # |d n_i|
            row = axis + (arm / scale) * (turn[:, None] + axis)  # |d J_h row i|
            jac = np.sqrt(6.0) * row.max(axis=1)
            s1, s6 = self.sigma[:, 0], self.sigma[:, -1]
            cond = np.where(jac < s6, jac * (s1 + s6) / (s6 * (s6 - jac)), np.inf)
            exact = half * self.cond_terms[:, 0] + 0.5 * half**2 * self.cond_terms[:, 1]
            cond = np.where(np.isnan(exact), cond, exact)  # near the limit: the measured slope and curvature
        m = MARGIN_SAFETY
        first = m * half[:, None, None] * self.sensitivity
        return (first[:, 0] + hinge[:, None] ** 2 / arm, first[:, 1] + axis**2,
                first[:, 2] + (axis + turn[:, None]) ** 2, m * cond)

    def _parts(self, robot: Robot, half):
        """Distance to each limit after the margins: d_z / 1 cm, universal and spherical (rad) [n, 6] and the
        relative condition number [n, 1] (negative: violated or not proven; NaN counts as violated)."""
        lim = robot.limits
        dz, mu, ms, mc = self.margins(robot, half)
        with np.errstate(invalid="ignore"):
            parts = [(self.d[..., 2] - dz) / 0.01, lim.universal_joint_max - self.universal - mu,
                     lim.spherical_joint_max - self.spherical - ms,
                     ((lim.condition_number_max - self.condition - mc) / lim.condition_number_max)[:, None]]
        return [np.where(np.isnan(p), -np.inf, p) for p in parts]

    def slack(self, robot: Robot, half) -> np.ndarray:
        """Smallest distance to a limit after the margins [n] (negative: violated or not proven)."""
        return np.min([p.min(axis=1) for p in self._parts(robot, half)], axis=0)

    def raise_violation(self, robot: Robot, i: int, half, time: float, what: str) -> None:
        """Raise the typed error of sample ``i``'s tightest limit (its slack with the margins of ``half`` [n] is
        negative)."""
        lim = robot.limits
        parts = [p[i] for p in self._parts(robot, half)]
        which = int(np.argmin([p.min() for p in parts]))
        leg = int(np.argmin(parts[which]))
        _, mu, ms, _ = (x[i] for x in self.margins(robot, half))
        where = f"at t = {time:.4f} s"
        tolerance = (f" (+{np.degrees(max(mu[leg], ms[leg])):.3f} deg for the sampling and the vibration units' "
                     "reach)") if half[i] > 0 else ""
        if which == 0:
            raise UnreachablePoseError(
                f"workspace limit {where}: {what} takes the platform hinge of leg {leg + 1} to the base hinge plane "
                f"(d_z = {self.d[i, leg, 2]:.6g} m)", leg=leg + 1, limit_name="hinge_above_base",
                value=float(self.d[i, leg, 2]), limit=0.0, time=time)
        if which in (1, 2):
            angles, limit, name, label = ((self.universal[i], lim.universal_joint_max, "universal_joint_max",
                                           "universal (base)") if which == 1 else
                                          (self.spherical[i], lim.spherical_joint_max, "spherical_joint_max",
                                           "spherical (platform)"))
            raise JointLimitError(
                f"joint limit {where}: {what} takes the {label} joint of leg {leg + 1} to "
                f"{np.degrees(angles[leg]):.3f} deg{tolerance}, limit {np.degrees(limit):.3f} deg ({name})",
                leg=leg + 1, limit_name=name, value=float(angles[leg]), limit=limit, time=time)
        raise SingularPoseError(
            f"near-singular pose {where}: {what} reaches condition number {self.condition[i]:.4g}, "
            f"limit {lim.condition_number_max:.4g} (condition_number_max)", limit_name="condition_number_max",
            value=float(self.condition[i]), limit=lim.condition_number_max, time=time)


def _sensitivity(jac, r, axes, length, rot, universal, spherical) -> np.ndarray:
    """Sum over struts of |dq / dl_j| [n, 3, 6] for q = d_z (m/m), universal and spherical angle (rad/m) of each leg.

    With x = [dp; dphi] (dl = J x, J rows [n_i, r_i x n_i]) and dd_i = dp + dphi x r_i: d d_z,i = [e_z, r_i x
    e_z] x; the leg axis moves by dn_i = (I - n_i n_i') dd_i / l_i, so d cos(universal_i) = [w_i, r_i x w_i] x /
    l_i with w_i = e_z - n_z,i n_i, and d cos(spherical_i) = [v_i, r_i x v_i] x / l_i + [0, z_p x n_i] x with
    z_p = R e_z, v_i = z_p - (n_i . z_p) n_i; dq / dl = (dq / dx) J^-1 (one batched solve)."""
    count = jac.shape[0]
    ez = np.array([0.0, 0.0, 1.0])
    zp = rot[:, :, 2][:, None, :]  # [n, 1, 3]
    w = ez - axes[..., 2:3] * axes
    v = zp - np.einsum("nij,nij->ni", axes, np.broadcast_to(zp, axes.shape))[..., None] * axes
    with np.errstate(divide="ignore", invalid="ignore"):
        rows = np.concatenate([
            np.concatenate([np.broadcast_to(ez, r.shape), cross(r, np.broadcast_to(ez, r.shape))], axis=-1),
            -np.concatenate([w, cross(r, w)], axis=-1) / (length * np.sin(universal))[..., None],
            -(np.concatenate([v, cross(r, v)], axis=-1) / length[..., None]
              + np.concatenate([np.zeros_like(v), cross(np.broadcast_to(zp, axes.shape), axes)], axis=-1))
            / np.sin(spherical)[..., None]], axis=1)  # [n, 18, 6]: d q / d x
    try:
        per_length = np.linalg.solve(np.transpose(jac, (0, 2, 1)), np.transpose(rows, (0, 2, 1)))  # [n, 6, 18]
    except np.linalg.LinAlgError:
        per_length = np.full((count, 6, 18), np.inf)
    total = np.abs(per_length).sum(axis=1).reshape(count, 3, 6)
    return np.where(np.isfinite(total), total, np.inf)


def _condition_terms(robot: Robot, poses, rot, jac, condition) -> np.ndarray:
    """[n, 2]: sum over struts j of |d cond / d l_j| and of |d2 cond / d l_j^2| by central differences (strut
    steps of COND_STEP_M, the pose moved by J^-1 e_j per metre), where cond > COND_EXACT_ABOVE x its limit;
    NaN elsewhere (the Weyl bound is tight enough there)."""
    out = np.full((len(poses), 2), np.nan)
    near = np.flatnonzero(condition > COND_EXACT_ABOVE * robot.limits.condition_number_max)
    if not near.size:
        return out
    try:
        moves = np.linalg.inv(jac[near]) * COND_STEP_M  # [k, 6 (x), 6 (strut j)]
    except np.linalg.LinAlgError:
        return out
    shifted = []
    for sign in (1.0, -1.0):
        dx = sign * np.transpose(moves, (0, 2, 1))  # [k, j, 6]
        position = poses[near, None, :3] + dx[..., :3]
        turned = so3_exp(dx[..., 3:]) @ rot[near, None]
        shifted.append(condition_number(robot, np.concatenate([position, rpy_from_rotation(turned)], axis=-1)))
    centre = condition[near, None]
    out[near, 0] = np.abs(shifted[0] - shifted[1]).sum(axis=1) / (2 * COND_STEP_M)
    out[near, 1] = np.abs(shifted[0] - 2 * centre + shifted[1]).sum(axis=1) / COND_STEP_M**2
    return np.where(np.isfinite(out) | np.isnan(out), out, np.inf)

