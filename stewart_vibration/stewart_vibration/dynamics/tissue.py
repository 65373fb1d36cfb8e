"""Soft tissue around the fracture as a 6-DoF visco-elastic load on the platform (pure numpy).

The distal fragment (held by the platform) is pulled back by muscles and ligaments as it is distracted
and aligned. The model is a spring-damper about a rest pose -- the platform pose at which the tissue is
slack -- acting at a tissue centre fixed in the platform (e.g. the fracture gap on the tibia axis), with
separate stiffness and damping per direction in the tissue frame: the platform frame at the rest pose,
whose z axis is the tibia axis (axial), x and y lateral, rotation about z torsion, about x and y bending.

With R_r, p_r the rest rotation and position, c the centre (platform frame), R, p, v, w the platform's
rotation, origin, origin velocity and angular velocity (base frame) and r = R c:

    u     = R_r^T (p + r - p_r - R_r c)          translation of the centre, tissue frame (u_z > 0: distraction)
    theta = log(R_r^T R)                         rotation from the rest pose, tissue frame (rotation vector)
    v_t   = R_r^T (v + w x r),  w_t = R_r^T w    their rates
    F_t   = -[k_lat u_x + c_lat v_x,  k_lat u_y + c_lat v_y,  preload + f(u_z) + c_ax v_z]
    M_t   = -[k_bend theta_x + c_bend w_x,  k_bend theta_y + c_bend w_y,  k_tor theta_z + c_tor w_z]

f is the axial spring: k_ax u in compression (u <= 0); in distraction either linear, exponential
k_ax lambda (exp(u / lambda) - 1) (slope k_ax at 0, growing e-fold every lambda), or piecewise linear
(slopes k_j from breakpoints u_j). The preload (N, >= 0) pulls the fragment back along the axis (toward
the base) at any distraction: muscle tone. The wrench on the platform, base frame, moment about the
platform origin (the convention of ``dynamics.leg_forces`` and platform/external_wrench_estimate):

    F = R_r F_t,   M = R_r M_t + r x F

Parameters come from a YAML file (config/tissue.yaml holds EXAMPLE values, not patient data);
``tissue_config.load_tissue`` reads it and ``tissue_bounds`` checks its worst-case wrench. ``tissue_wrench``
is vectorised over leading batch dimensions; ``tissue_wrench_from_state`` takes rotation matrices (the
emulator's MuJoCo state) instead of roll-pitch-yaw. ``wrench_about_point`` moves the moment to another point,
e.g. the centre of mass for MuJoCo's ``xfrc_applied`` (force at the body's centre of mass, world frame).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, cast

import numpy as np

from ..input_checks import as_batch
from ..kinematics.rotations import rotation_from_rpy, so3_log
from ..robot import read_only_array


@dataclass(frozen=True)
class TissueModel:
    """Tissue parameters (SI). rest_pose (6,) [x, y, z, roll, pitch, yaw]; center (3,) platform frame (m);
    stiffness (6,) [lateral, lateral, axial (N/m), bending, bending, torsional (N m/rad)] and damping (6,)
    (N s/m, N m s/rad) in the tissue frame; preload (N, pulls back along the axis); stiffening "none" |
    "exponential" (length_m) | "piecewise_linear" (breakpoints_m [n] from 0 up, slopes_n_m [n], the first
    equal to the axial stiffness)."""

    rest_pose: np.ndarray
    center: np.ndarray
    stiffness: np.ndarray
    damping: np.ndarray
    preload: float = 0.0
    stiffening: str = "none"
    length_m: float = 0.0
    breakpoints_m: np.ndarray | None = None
    slopes_n_m: np.ndarray | None = None
    name: str = "tissue"
    source: str = ""

    if TYPE_CHECKING:  # derived in __post_init__ (not fields at run time)
        _rest: np.ndarray = field(init=False)
        _rest_center: np.ndarray = field(init=False)
        _rest_list: list[list[float]] = field(init=False)
        _rest_center_list: list[float] = field(init=False)
        _center_list: list[float] = field(init=False)
        _stiffness_list: list[float] = field(init=False)
        _damping_list: list[float] = field(init=False)

    def __post_init__(self):
        for name in ("rest_pose", "center", "stiffness", "damping", "breakpoints_m", "slopes_n_m"):
            if getattr(self, name) is not None:  # read-only: the plain-float copies below must stay in step
                object.__setattr__(self, name, read_only_array(getattr(self, name)))
        rest = rotation_from_rpy(self.rest_pose[3:])
        object.__setattr__(self, "_rest", rest)
        object.__setattr__(self, "_rest_center", self.rest_pose[:3] + rest @ self.center)
        # plain-float copies for tissue_wrench_single
        object.__setattr__(self, "_rest_list", rest.tolist())
        object.__setattr__(self, "_rest_center_list", self._rest_center.tolist())
        object.__setattr__(self, "_center_list", self.center.tolist())
        object.__setattr__(self, "_stiffness_list", self.stiffness.tolist())
        object.__setattr__(self, "_damping_list", self.damping.tolist())

    @property
    def rest_rotation(self) -> np.ndarray:
        """The platform's rotation at the rest pose (3, 3): tissue frame -> base frame."""
        return self._rest

    @property
    def rest_center(self) -> np.ndarray:
        """The centre at the rest pose, base frame (m)."""
        return self._rest_center

    @property
    def axis(self) -> np.ndarray:
        """The tibia axis (tissue z) in the base frame."""
        return self._rest[:, 2].copy()

    def axial_spring(self, distraction) -> np.ndarray:
        """Axial spring force f(u) (N, resisting) at axial displacements u [...] (m); without the preload."""
        u = np.asarray(distraction, dtype=float)
        k = self.stiffness[2]
        pos = np.maximum(u, 0.0)
        if self.stiffening == "exponential":
            grown = k * self.length_m * np.expm1(pos / self.length_m)
        elif self.stiffening == "piecewise_linear":
            # both set with this stiffening (load_tissue checks them)
            starts, slopes = cast(np.ndarray, self.breakpoints_m), cast(np.ndarray, self.slopes_n_m)
            ends = np.append(starts[1:], np.inf)
            grown = sum(s * np.clip(pos - a, 0.0, b - a) for a, b, s in zip(starts, ends, slopes))
        else:
            grown = k * pos
        return np.where(u > 0, grown, k * u)

    def axial_spring_scalar(self, u: float) -> float:
        """``axial_spring`` for one float (plain Python: the emulator's per-block path)."""
        k = self._stiffness_list[2]
        if u <= 0.0 or self.stiffening == "none":
            return k * u
        if self.stiffening == "exponential":
            return k * self.length_m * math.expm1(u / self.length_m)
        return float(self.axial_spring(u))


def _cross(a, b):
    """a x b over the last axis (np.cross costs ~20 us per call on one vector: the emulator calls this per block)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a1 * b2 - a2 * b1
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


def tissue_displacement(model: TissueModel, position, rotation):
    """(u [..., 3] m, theta [..., 3] rad, arm r = R c [..., 3]) of the tissue centre, tissue frame.

    Args:
        model: the tissue model.
        position: platform origins p [..., 3] (base frame, m).
        rotation: platform rotations R [..., 3, 3].

    Returns:
        (u, theta, arm): u = R_r^T (p + R c - p_r - R_r c) [..., 3] (m) and theta = log(R_r^T R) [..., 3]
        (rad), both in the tissue frame; arm r = R c [..., 3] (base frame, m).
    """
    rest = model.rest_rotation
    arm = rotation @ model.center
    u = (position + arm - model.rest_center) @ rest
    return u, so3_log(rest.T @ rotation), arm


def tissue_wrench_from_state(model: TissueModel, position, rotation, velocity=None, omega=None) -> np.ndarray:
    """Wrench [..., 6] = [F, M] (N, N m about the platform origin, base frame) of the tissue on the platform at
    positions [..., 3], rotations [..., 3, 3] and, optionally, origin velocities and angular velocities [..., 3].

    Args:
        model: the tissue model.
        position: platform origins p [..., 3] (base frame, m).
        rotation: platform rotations R [..., 3, 3].
        velocity: optional origin velocities v [..., 3] (base frame, m/s); None = at rest: no damping.
        omega: optional angular velocities w [..., 3] (base frame, rad/s); None = 0; ignored when
            ``velocity`` is None.

    Returns:
        [F, M] [..., 6] (N, N m about the platform origin; base frame).
    """
    u, theta, arm = tissue_displacement(model, position, rotation)
    k, c = model.stiffness, model.damping
    force_t = -k[:3] * u
    force_t[..., 2] = -(model.preload + model.axial_spring(u[..., 2]))
    moment_t = -k[3:] * theta
    if velocity is not None:
        rest = model.rest_rotation
        omega = np.zeros_like(velocity) if omega is None else omega
        force_t = force_t - c[:3] * ((velocity + _cross(omega, arm)) @ rest)
        moment_t = moment_t - c[3:] * (omega @ rest)
    rest_t = model.rest_rotation.T
    force = force_t @ rest_t
    moment = moment_t @ rest_t + _cross(arm, force)
    return np.concatenate([force, moment], axis=-1)


def tissue_wrench_single(model: TissueModel, position, rotation, velocity, omega) -> list[float]:
    """``tissue_wrench_from_state`` for one state in plain Python floats (~10x faster than numpy on 3-vectors:
    the emulator evaluates it every state period).

    Args:
        model: the tissue model.
        position: platform origin p (3,) (base frame, m).
        rotation: platform rotation R, a (3, 3) numpy array.
        velocity: origin velocity v (3,) (base frame, m/s).
        omega: angular velocity w (3,) (base frame, rad/s).

    Returns:
        [F_x, F_y, F_z, M_x, M_y, M_z] as six floats (N, N m about the platform origin; base frame).
    """
    px, py, pz = position[0], position[1], position[2]
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = rotation.tolist()
    cx, cy, cz = model._center_list
    ax, ay, az = r00 * cx + r01 * cy + r02 * cz, r10 * cx + r11 * cy + r12 * cz, r20 * cx + r21 * cy + r22 * cz
    (q00, q01, q02), (q10, q11, q12), (q20, q21, q22) = model._rest_list
    ox, oy, oz = model._rest_center_list
    dx, dy, dz = px + ax - ox, py + ay - oy, pz + az - oz
    u0, u1, u2 = q00 * dx + q10 * dy + q20 * dz, q01 * dx + q11 * dy + q21 * dz, q02 * dx + q12 * dy + q22 * dz
    # rel = R_r^T R and its rotation vector (so3_log)
    m = [[q00 * r00 + q10 * r10 + q20 * r20, q00 * r01 + q10 * r11 + q20 * r21, q00 * r02 + q10 * r12 + q20 * r22],
         [q01 * r00 + q11 * r10 + q21 * r20, q01 * r01 + q11 * r11 + q21 * r21, q01 * r02 + q11 * r12 + q21 * r22],
         [q02 * r00 + q12 * r10 + q22 * r20, q02 * r01 + q12 * r11 + q22 * r21, q02 * r02 + q12 * r12 + q22 * r22]]
    angle = math.acos(min(1.0, max(-1.0, (m[0][0] + m[1][1] + m[2][2] - 1.0) / 2.0)))
    sin = math.sin(angle)
    scale = 0.5 + angle * angle / 12.0 if angle < 1e-6 else angle / (2.0 * (sin if sin != 0 else 1.0))
    t0, t1, t2 = scale * (m[2][1] - m[1][2]), scale * (m[0][2] - m[2][0]), scale * (m[1][0] - m[0][1])
    kx, ky, kz, kbx, kby, ktz = model._stiffness_list
    cxd, cyd, czd, cbx, cby, ctz = model._damping_list
    wx, wy, wz = omega[0], omega[1], omega[2]
    vx, vy, vz = velocity[0] + wy * az - wz * ay, velocity[1] + wz * ax - wx * az, velocity[2] + wx * ay - wy * ax
    vt0, vt1, vt2 = q00 * vx + q10 * vy + q20 * vz, q01 * vx + q11 * vy + q21 * vz, q02 * vx + q12 * vy + q22 * vz
    wt0, wt1, wt2 = q00 * wx + q10 * wy + q20 * wz, q01 * wx + q11 * wy + q21 * wz, q02 * wx + q12 * wy + q22 * wz
    f0, f1 = -kx * u0 - cxd * vt0, -ky * u1 - cyd * vt1
    f2 = -(model.preload + model.axial_spring_scalar(u2)) - czd * vt2
    m0, m1, m2 = -kbx * t0 - cbx * wt0, -kby * t1 - cby * wt1, -ktz * t2 - ctz * wt2
    fx, fy, fz = q00 * f0 + q01 * f1 + q02 * f2, q10 * f0 + q11 * f1 + q12 * f2, q20 * f0 + q21 * f1 + q22 * f2
    mx = q00 * m0 + q01 * m1 + q02 * m2 + ay * fz - az * fy
    my = q10 * m0 + q11 * m1 + q12 * m2 + az * fx - ax * fz
    mz = q20 * m0 + q21 * m1 + q22 * m2 + ax * fy - ay * fx
    return [fx, fy, fz, mx, my, mz]


def tissue_wrench(model: TissueModel, pose, twist=None) -> np.ndarray:
    """Wrench [..., 6] of the tissue on the platform at poses [..., 6] with optional twists [..., 6] = [v, w]
    (base frame; None = at rest). Base frame, moment about the platform origin (see the module docstring).

    Args:
        model: the tissue model.
        pose: platform poses [..., 6] (m, rad).
        twist: optional platform twists [..., 6] = [v, w] (m/s, rad/s; base frame), broadcast against
            ``pose``; None = at rest (no damping).

    Returns:
        [F, M] [..., 6] (N, N m about the platform origin; base frame).

    Raises:
        InvalidInputError: ``pose`` or ``twist`` is not numeric, not [..., 6] or not finite (``as_batch``).
        ValueError: the batch shapes of ``pose`` and ``twist`` do not broadcast (numpy).
    """
    pose = as_batch(pose, 6, "pose")
    if twist is None:
        return tissue_wrench_from_state(model, pose[..., :3], rotation_from_rpy(pose[..., 3:]))
    twist = as_batch(twist, 6, "twist")
    pose, twist = np.broadcast_arrays(pose, twist)
    return tissue_wrench_from_state(model, pose[..., :3], rotation_from_rpy(pose[..., 3:]), twist[..., :3],
                                    twist[..., 3:])


def wrench_about_point(wrench, arm) -> np.ndarray:
    """The same wrench [..., 6] with its moment about the point at ``arm`` [..., 3] from the original
    reference point: [F, M - arm x F] (e.g. the centre of mass for MuJoCo's xfrc_applied).

    Args:
        wrench: wrenches [..., 6] = [F, M] (N, N m) about the original reference point.
        arm: vectors [..., 3] (m) from the original reference point to the new one, in the wrench's frame.

    Returns:
        [F, M - arm x F] [..., 6] (N, N m about the new point).
    """
    wrench = np.asarray(wrench, dtype=float)
    force = wrench[..., :3]
    return np.concatenate([force, wrench[..., 3:] - _cross(arm, force)], axis=-1)


__all__ = [
    "TissueModel",
    "tissue_displacement",
    "tissue_wrench",
    "tissue_wrench_from_state",
    "tissue_wrench_single",
    "wrench_about_point",
]
