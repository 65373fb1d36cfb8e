"""MuJoCo simulation of the generated 6-UPS model: state setting, driving, read-back.

``StewartSim`` is the API for the validation and the hardware emulator:
build from a Robot, put the robot in a consistent state at a pose, step with
six axial forces or track leg-length targets (computed-force drive), read leg
lengths / velocities / actuator forces and the platform pose / twist /
acceleration. SI units, base frame, pose = [x, y, z, roll, pitch, yaw],
twist [v, w] / accel [a, alpha] of the platform origin (base frame).

Vibration (the ``vib_i`` joints of the design): the vibration unit sits in
series with the strut on the same leg axis, so what the platform feels is the
total hinge-to-hinge length leg_i + vib_i, and both carry the same axial
force. The model therefore has one slide per leg whose position is the total
length; ``step_tracking(..., vib=...)`` adds the vibration displacement (and
its rates) to the strut target. The vibration unit's moving mass is lumped
into the piston (see ``Robot.leg_bodies``).

``closed_chain_forces`` is the exact static check: at a consistent state it
solves MuJoCo's own equations [B J_c^T] [F; lambda] = M qacc + c.
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..input_checks import as_batch
from ..kinematics import leg_vectors
from ..kinematics.legs import leg_motion
from ..kinematics.rotations import quaternion_from_rpy, rotation_from_rpy, rpy_from_rotation
from ..robot import LEG_NAMES, Robot
from .mjcf import SimulationSettings, UnitSliders, build_model, leg_frame


class StewartSim:
    """One MuJoCo model + data of the robot (see module docstring).

    base_joint: "universal" (the real robot) or "ball" (exact static check).
    gain_interval: recompute the drive's force-to-acceleration matrix every
    this many steps (1 = exact computed-force drive, used by the validation;
    larger is faster, the feedback absorbs the slowly changing gain).
    units: the vibration units as slider bodies (``mjcf.UnitSliders``; the emulated robot as built); the
    slides ``leg_i`` are then the struts alone.
    Attributes: model, data (mujoco), robot, settings.
    """

    def __init__(self, robot: Robot, settings: SimulationSettings | None = None, base_joint: str = "universal",
                 gain_interval: int = 1, units: UnitSliders | None = None):
        self.robot = robot
        self.gain_interval = max(1, int(gain_interval))
        self._gain: np.ndarray | None
        self._gain, self._gain_age = None, 0
        self.settings = settings or SimulationSettings()
        self.base_joint = base_joint
        self.model = build_model(robot, self.settings, base_joint, units)
        self.data = mujoco.MjData(self.model)
        self._scratch = mujoco.MjData(self.model)
        m = self.model
        jid = [m.joint(name).id for name in LEG_NAMES]
        self.slide_qpos = np.array([m.jnt_qposadr[j] for j in jid])
        self.slide_dof = np.array([m.jnt_dofadr[j] for j in jid])
        first = "u1" if base_joint == "universal" else "ball"
        self.base_qpos = np.array([m.jnt_qposadr[m.joint(f"{first}_{i}").id] for i in range(1, 7)])
        self.base_dof = np.array([m.jnt_dofadr[m.joint(f"{first}_{i}").id] for i in range(1, 7)])
        free = m.joint("platform").id
        self.free_qpos, self.free_dof = int(m.jnt_qposadr[free]), int(m.jnt_dofadr[free])
        self.actuator_map = np.zeros((m.nv, m.nu))  # B: generalised force = B F
        for k in range(m.nu):
            self.actuator_map[m.jnt_dofadr[m.actuator_trnid[k, 0]], k] = m.actuator_gear[k, 0]
        d0 = leg_vectors(robot, robot.home_pose)
        self.leg_frames = np.stack([leg_frame(v / np.linalg.norm(v)) for v in d0])  # F0_i (6, 3, 3)
        omega = 2 * np.pi * self.settings.drive_bandwidth_hz
        self.kp, self.kd = omega**2, 2 * self.settings.drive_damping_ratio * omega

    # -- state ---------------------------------------------------------------
    def reset(self, pose=None) -> None:
        """Reset time and put the robot at rest at ``pose`` (default home)."""
        mujoco.mj_resetData(self.model, self.data)
        self._gain = None
        self.set_state(self.robot.home_pose if pose is None else pose)

    def set_state(self, pose, twist=None, accel=None, data=None) -> np.ndarray | None:
        """Set a kinematically consistent state (platform and all leg joints) and run mj_forward.

        pose, twist, accel: (6,) (twist/accel default 0). Leg spin is zero with
        ball joints; with universal joints it is what the U-joint imposes.
        Returns the consistent qacc (nv,) if ``accel`` is given (for
        ``closed_chain_forces``), else None.
        """
        data = self.data if data is None else data
        pose = as_batch(pose, 6, "pose").reshape(6)
        twist = np.zeros(6) if twist is None else as_batch(twist, 6, "twist").reshape(6)
        acc6 = np.zeros(6) if accel is None else as_batch(accel, 6, "accel").reshape(6)
        lm = leg_motion(self.robot, pose, twist, acc6)
        rot = lm.rotation
        qpos, qvel, qacc = data.qpos, data.qvel, np.zeros(self.model.nv)
        xyzw = quaternion_from_rpy(pose[3:])
        qpos[self.free_qpos:self.free_qpos + 7] = np.r_[pose[:3], xyzw[3], xyzw[:3]]
        fd = self.free_dof
        qvel[fd:fd + 6] = np.r_[twist[:3], rot.T @ twist[3:]]
        qacc[fd:fd + 6] = np.r_[acc6[:3], rot.T @ acc6[3:]]
        qpos[self.slide_qpos], qvel[self.slide_dof], qacc[self.slide_dof] = (
            lm.length, lm.length_rate, lm.length_accel)
        for i in range(6):
            f0 = self.leg_frames[i]
            s, sd, sdd = f0.T @ lm.axis[i], f0.T @ lm.axis_rate[i], f0.T @ lm.axis_accel[i]
            qa, da = self.base_qpos[i], self.base_dof[i]
            if self.base_joint == "universal":
                q, qd, qdd = universal_angles(s, sd, sdd)
                qpos[qa:qa + 2], qvel[da:da + 2], qacc[da:da + 2] = q, qd, qdd
            else:
                quat, rel = _ball_quat(s)
                r_cyl = f0 @ rel
                qpos[qa:qa + 4] = quat
                qvel[da:da + 3] = r_cyl.T @ lm.omega[i]
                qacc[da:da + 3] = r_cyl.T @ lm.alpha[i]
        mujoco.mj_forward(self.model, data)
        return qacc if accel is not None else None

    # -- stepping ------------------------------------------------------------
    def step(self, forces) -> None:
        """One time step with the six axial actuator forces (N, positive extends the leg)."""
        self.data.ctrl[:] = as_batch(forces, 6, "forces").reshape(6)
        mujoco.mj_step(self.model, self.data)

    def drive_forces(self, length, rate=None, accel=None) -> np.ndarray:
        """Computed-force drive: the six forces giving l_ddot = accel + kd (rate - l_dot) + kp (length - l).

        length, rate, accel: leg targets (6,) (m, m/s, m/s^2; rates default 0).
        Exact because MuJoCo's acceleration is affine in the actuator forces
        (equality-only constraints, Newton solver): qacc(F) = qacc(0) + G F.
        """
        m, d = self.model, self.data
        rate = np.zeros(6) if rate is None else np.asarray(rate, dtype=float)
        accel = np.zeros(6) if accel is None else np.asarray(accel, dtype=float)
        want = accel + self.kd * (rate - self.leg_velocities()) + self.kp * (length - self.leg_lengths())
        saved = d.ctrl.copy()
        d.ctrl[:] = 0.0
        mujoco.mj_forward(m, d)
        base = d.qacc[self.slide_dof].copy()
        if self._gain is None or self._gain_age >= self.gain_interval:
            gain = np.empty((6, 6))
            for k in range(6):
                d.ctrl[:] = 0.0
                d.ctrl[k] = 1.0
                mujoco.mj_forwardSkip(m, d, mujoco.mjtStage.mjSTAGE_VEL, 1)
                gain[:, k] = d.qacc[self.slide_dof] - base
            self._gain, self._gain_age = gain, 0
        self._gain_age += 1
        d.ctrl[:] = saved
        return np.linalg.solve(self._gain, want - base)

    def step_tracking(self, length, rate=None, accel=None, vib=None, vib_rate=None, vib_accel=None) -> np.ndarray:
        """Step once toward strut targets plus optional vibration displacement (all (6,), SI).

        Target total length = length + vib (and likewise for the rates).
        Returns the six forces applied during the step (N).
        """
        def add(a, b):
            if b is None:
                return a
            return (np.zeros(6) if a is None else np.asarray(a, dtype=float)) + np.asarray(b, dtype=float)

        forces = self.drive_forces(add(length, vib), add(rate, vib_rate), add(accel, vib_accel))
        self.step(forces)
        return forces

    # -- read-back -----------------------------------------------------------
    @property
    def time(self) -> float:
        """Simulation time (s)."""
        return float(self.data.time)

    def leg_lengths(self, data=None) -> np.ndarray:
        """Total hinge-to-hinge strut lengths (6,) (m)."""
        return (self.data if data is None else data).qpos[self.slide_qpos].copy()

    def leg_velocities(self, data=None) -> np.ndarray:
        """Strut length rates (6,) (m/s)."""
        return (self.data if data is None else data).qvel[self.slide_dof].copy()

    def actuator_forces(self, data=None) -> np.ndarray:
        """Axial actuator forces (6,) (N) from the force sensors (valid after a step or mj_forward)."""
        return (self.data if data is None else data).sensordata[:6].copy()

    def platform_pose(self, data=None) -> np.ndarray:
        """Platform pose (6,) [x, y, z, roll, pitch, yaw] from the free joint."""
        data = self.data if data is None else data
        quat = data.qpos[self.free_qpos + 3:self.free_qpos + 7]
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, quat / np.linalg.norm(quat))
        return np.r_[data.qpos[self.free_qpos:self.free_qpos + 3], rpy_from_rotation(rot.reshape(3, 3))]

    def platform_position_quaternion(self, data=None) -> tuple[np.ndarray, np.ndarray]:
        """(position (3,) m, unit quaternion (4,) [x, y, z, w]) of the platform frame (base frame)."""
        data = self.data if data is None else data
        q = data.qpos[self.free_qpos:self.free_qpos + 7]  # MuJoCo keeps the quaternion normalised
        return q[:3].copy(), q[[4, 5, 6, 3]]

    def platform_twist(self, data=None) -> np.ndarray:
        """[v, w] (6,) of the platform origin, base frame (MuJoCo stores w in the body frame)."""
        data = self.data if data is None else data
        fd = self.free_dof
        rot = rotation_from_rpy(self.platform_pose(data)[3:])
        return np.r_[data.qvel[fd:fd + 3], rot @ data.qvel[fd + 3:fd + 6]]

    def platform_accel(self, data=None) -> np.ndarray:
        """[a, alpha] (6,) of the platform origin, base frame, from qacc (valid after mj_forward)."""
        data = self.data if data is None else data
        fd = self.free_dof
        rot = rotation_from_rpy(self.platform_pose(data)[3:])
        return np.r_[data.qacc[fd:fd + 3], rot @ data.qacc[fd + 3:fd + 6]]

    def constraint_violation(self, data=None) -> float:
        """Largest hinge gap |tip_i - a_i| (m) of the six leg-platform connects."""
        data = self.data if data is None else data
        gaps = [data.site(f"tip_{i}").xpos - data.site(f"a_{i}").xpos for i in range(1, 7)]
        return float(np.max(np.linalg.norm(gaps, axis=1)))

    def evaluate(self, qpos, qvel, forces):
        """Re-evaluate a recorded state with forces on a scratch MjData (mj_forward).

        Returns (pose, twist, accel, constraint violation) of that state: the
        acceleration MuJoCo's equations give for exactly these forces (not an
        RK4 stage).
        """
        d = self._scratch
        d.qpos[:], d.qvel[:], d.ctrl[:] = qpos, qvel, forces
        mujoco.mj_forward(self.model, d)
        return self.platform_pose(d), self.platform_twist(d), self.platform_accel(d), self.constraint_violation(d)


def universal_angles(s, sd, sdd):
    """Hinge angles (q1 about x, then q2 about the rotated y) and their rates for the leg axis
    s = Rx(q1) Ry(q2) z = [sin q2, -sin q1 cos q2, cos q1 cos q2] in the cylinder's home frame.

    Args:
        s: unit leg axis (3,) in the cylinder's home frame.
        sd: its time derivative (3,) (1/s).
        sdd: its second time derivative (3,) (1/s^2).

    Returns:
        (q, qd, qdd), each (2,) = [q1, q2]: angles (rad), rates (rad/s) and accelerations (rad/s^2);
        singular at cos q2 = 0.
    """
    q2 = np.arcsin(s[0])
    c2 = np.cos(q2)
    q2d = sd[0] / c2
    q2dd = (sdd[0] + np.sin(q2) * q2d**2) / c2
    y, z = -s[1], s[2]
    yd, zd, ydd, zdd = -sd[1], sd[2], -sdd[1], sdd[2]
    den = y * y + z * z
    num = z * yd - y * zd
    q1 = np.arctan2(y, z)
    q1d = num / den
    q1dd = ((z * ydd - y * zdd) * den - num * 2.0 * (y * yd + z * zd)) / den**2
    return np.array([q1, q2]), np.array([q1d, q2d]), np.array([q1dd, q2dd])


def _ball_quat(s):
    """Smallest rotation taking z to the unit vector s: (quaternion [w, x, y, z], matrix)."""
    axis = np.cross([0.0, 0.0, 1.0], s)
    sin = np.linalg.norm(axis)
    angle = np.arctan2(sin, s[2])
    quat = np.r_[1.0, 0.0, 0.0, 0.0] if sin < 1e-15 else np.r_[np.cos(angle / 2), np.sin(angle / 2) * axis / sin]
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, quat)
    return quat, rot.reshape(3, 3)
