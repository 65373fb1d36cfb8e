"""Platform motion from leg-space measurements and commands, for the leg-force estimator (pure numpy).

Leg space is the total hinge-to-hinge length L_i = strut (leg_i) + vibration
unit (vib_i). With the Jacobian J (rows [n_i, (R a_i) x n_i], base frame):

- twist  t = [v, w] = J^-1 L_dot           (velocity of the platform origin);
- accel  a = [a, alpha] = J^-1 (L_ddot - c), c_i = the velocity-product part of
  L_ddot_i = s_i . (w x (w x r_i)) + |v_A,perp|^2 / l_i, i.e. L_ddot at zero
  acceleration (``leg_kinematics.leg_motion``), which is the J_dot t term.

Commanded leg accelerations come from the trajectories the emulator follows:
``VibrationCommandBuffer`` mirrors the emulator's vib_* window buffer (cubic
Hermite on positions + velocities, a new window replaces buffered samples from
its first time on); leg_* trajectories use ``emulation.trajectory``'s
joint_trajectory_controller follower directly.

External wrench: leg_forces is affine in the external wrench W = [F_E, M_E]
(acting on the platform, moment about the platform origin, base frame) with
J^T dF = -W, so from measured and modelled (W = 0) axial forces
W = -J^T (F_measured - F_model). J^T (F_measured - F_model) itself is the
extra wrench the legs exert on the platform.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from .emulation.trajectory import _cubic
from .errors import InvalidInputError, SingularPoseError
from .kinematics import jacobian
from .leg_kinematics import leg_motion
from .validation import as_batch


def _solve(jac: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.solve(jac, rhs[..., None])[..., 0]
    except np.linalg.LinAlgError as exc:
        raise SingularPoseError("singular Jacobian: platform motion is not determined by the leg rates") from exc


def platform_twist(robot, pose, length_rate) -> np.ndarray:
    """Twist [..., 6] = [v, w] (m/s, rad/s, base frame) from hinge-length rates L_dot [..., 6] (m/s)."""
    pose = as_batch(pose, 6, "pose")
    rate = as_batch(length_rate, 6, "length_rate")
    return _solve(jacobian(robot, pose), rate)


def platform_accel(robot, pose, twist, length_accel) -> np.ndarray:
    """Acceleration [..., 6] = [a, alpha] of the platform origin from L_ddot [..., 6] (m/s^2) and the twist."""
    pose = as_batch(pose, 6, "pose")
    twist = as_batch(twist, 6, "twist")
    acc = as_batch(length_accel, 6, "length_accel")
    velocity_part = leg_motion(robot, pose, twist, np.zeros_like(twist)).length_accel
    return _solve(jacobian(robot, pose), acc - velocity_part)


def external_wrench(robot, pose, measured, model) -> np.ndarray:
    """External wrench on the platform [..., 6] = -J^T (F_measured - F_model) (N, N m about the platform origin)."""
    jac = jacobian(robot, as_batch(pose, 6, "pose"))
    diff = as_batch(measured, 6, "measured") - as_batch(model, 6, "model")
    return -np.einsum("...ij,...i->...j", jac, diff)


class VibrationCommandBuffer:
    """Commanded vib_* (positions, velocities) on absolute times, sampled like the emulator.

    ``add`` takes one window (absolute sample times [n], positions and
    velocities [n, 6]); buffered samples at or after its first time are
    replaced, samples older than ``history_s`` before it are dropped. Outside
    the buffered span the command is at rest (zero acceleration).
    """

    def __init__(self, history_s: float = 2.0):
        self.history_s = float(history_s)
        self.times = np.empty(0)
        self.positions = np.empty((0, 6))
        self.velocities = np.empty((0, 6))

    def add(self, times, positions, velocities) -> None:
        times = np.asarray(times, dtype=float)
        pos = np.asarray(positions, dtype=float).reshape(-1, 6)
        vel = np.asarray(velocities, dtype=float).reshape(-1, 6)
        if times.ndim != 1 or times.size == 0 or pos.shape[0] != times.size or vel.shape[0] != times.size:
            raise InvalidInputError("vibration window: times, positions and velocities must have one row per point")
        if not (np.isfinite(times).all() and np.isfinite(pos).all() and np.isfinite(vel).all()):
            raise InvalidInputError("vibration window: non-finite values")
        if (np.diff(times) <= 0).any():
            raise InvalidInputError("vibration window: times must be strictly increasing")
        keep = (self.times < times[0]) & (self.times >= times[0] - self.history_s)
        self.times = np.concatenate([self.times[keep], times])
        self.positions = np.vstack([self.positions[keep], pos])
        self.velocities = np.vstack([self.velocities[keep], vel])

    def sample(self, times):
        """(positions, velocities, accelerations) [n, 6] at absolute times [n] (s)."""
        t = np.atleast_1d(np.asarray(times, dtype=float))
        out = [np.zeros((t.size, 6)) for _ in range(3)]
        bt = self.times
        if bt.size < 2:
            return tuple(out)
        inside = (t >= bt[0]) & (t <= bt[-1])
        if inside.any():
            ti = t[inside]
            seg = np.clip(np.searchsorted(bt, ti, side="right") - 1, 0, bt.size - 2)
            h = (bt[seg + 1] - bt[seg])[:, None]
            s = (ti - bt[seg])[:, None] / h
            p, v, a = _cubic(s, h, self.positions[seg], self.velocities[seg],
                             self.positions[seg + 1], self.velocities[seg + 1])
            out[0][inside], out[1][inside], out[2][inside] = p, v, a
        out[0][t > bt[-1]] = self.positions[-1]  # held at rest after the last sample
        return tuple(out)


class RunningForceError:
    """RMS of F_measured - F_model over the last ``window_s`` seconds, and the force amplitude.

    amplitude: per leg half the peak-to-peak of the measured force in the window
    (the vibration's force amplitude); relative error = RMS error / RMS over the
    legs of those amplitudes.
    """

    def __init__(self, window_s: float = 1.0):
        self.window_s = float(window_s)
        self._samples: deque = deque()

    def add(self, stamp: float, measured, model) -> None:
        self._samples.append((float(stamp), np.asarray(measured, float), np.asarray(model, float)))
        while self._samples and self._samples[0][0] < stamp - self.window_s:
            self._samples.popleft()
        if self._samples and self._samples[0][0] > stamp:  # time went backwards (sim reset): restart
            self._samples = deque([self._samples[-1]])

    def __len__(self) -> int:
        return len(self._samples)

    def summary(self) -> dict:
        """rms_error_n (6,), rms_error_all_n, force_amplitude_n (6,), relative_error, samples."""
        if not self._samples:
            return {"samples": 0}
        measured = np.array([m for _, m, _ in self._samples])
        model = np.array([f for _, _, f in self._samples])
        err = measured - model
        rms = np.sqrt((err**2).mean(axis=0))
        amp = (measured.max(axis=0) - measured.min(axis=0)) / 2.0
        rms_all = float(np.sqrt((err**2).mean()))
        amp_all = float(np.sqrt((amp**2).mean()))
        return {
            "samples": len(self._samples),
            "rms_error_n": rms,
            "rms_error_all_n": rms_all,
            "force_amplitude_n": amp,
            "relative_error": rms_all / amp_all if amp_all > 0 else float("inf"),
        }


__all__ = [
    "RunningForceError",
    "VibrationCommandBuffer",
    "external_wrench",
    "platform_accel",
    "platform_twist",
]
