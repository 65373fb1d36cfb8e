"""Soft tissue on the emulated platform (no rclpy): the wrench of a ``dynamics.tissue.TissueModel`` evaluated
from the platform's state at the start of every block and applied over the block as MuJoCo's ``xfrc_applied``
on the platform body (force at the body's centre of mass and the moment about it, world frame: the tissue's
moment about the platform origin minus (R c_m) x F).
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..dynamics.tissue import TissueModel, tissue_wrench_single
from ..sim.mujoco_sim import StewartSim


def apply_tissue_wrench(sim: StewartSim, tissue: TissueModel, body: int, com: list[float],
                        rotation: np.ndarray) -> np.ndarray:
    """Evaluate ``tissue``'s wrench at ``sim``'s current state and apply it to ``body`` (the platform) until the
    next call (xfrc_applied); returns it (6,) (N, N m about the platform origin, base frame). ``com``: the
    body's centre of mass (m, body frame); ``rotation``: a (9,) buffer the platform's rotation is written to."""
    data = sim.data
    q = data.qpos[sim.free_qpos:sim.free_qpos + 7]
    qv = data.qvel[sim.free_dof:sim.free_dof + 6]
    mujoco.mju_quat2Mat(rotation, q[3:7])
    rot = rotation.reshape(3, 3)
    omega = (rot @ qv[3:6]).tolist()  # MuJoCo keeps the free joint's angular velocity in the body frame
    w = tissue_wrench_single(tissue, q[:3].tolist(), rot, qv[:3].tolist(), omega)
    cx, cy, cz = com
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = rot.tolist()
    ax, ay, az = r00 * cx + r01 * cy + r02 * cz, r10 * cx + r11 * cy + r12 * cz, r20 * cx + r21 * cy + r22 * cz
    fx, fy, fz = w[0], w[1], w[2]
    # xfrc_applied: force at the centre of mass, moment about it (world frame)
    data.xfrc_applied[body] = (fx, fy, fz, w[3] - (ay * fz - az * fy), w[4] - (az * fx - ax * fz),
                               w[5] - (ax * fy - ay * fx))
    return np.array(w)
