"""The emulated strut servos: a PD position loop inside MuJoCo plus a computed-force feedforward,
stepped in blocks so that Python is touched once per block, not once per physics step (no rclpy).

Each leg's ``general`` actuator (see mjcf) applies F = ctrl - kp L - kv L_dot, i.e. a PD servo on
the hinge-to-hinge length L around the reference folded into ctrl:

    ctrl_k = F_ff,k + kp L_ref(t_k) + kv L_dot_ref,k

The feedforward makes the legs follow the reference acceleration exactly when the model is right:
MuJoCo's leg accelerations are affine in the six forces, L_ddot = b + G F (b: the accelerations
with zero actuator force at the block's start state; G: their 6x6 sensitivity, refreshed every
``gain_interval`` blocks), so F_ff,k = G^-1 (L_ddot_ref(t_k) - b_k), with b_k extrapolated
linearly from the previous block. The PD only corrects what the block-wise model misses.

Integration is MuJoCo's semi-implicit Euler (v' = v + a dt, L' = L + v' dt): it reproduces the
reference lengths at every step when the step's acceleration is their second difference
(L_ref[k+1] - 2 L_ref[k] + L_ref[k-1]) / dt^2; its velocities then live half a step back, so the
rate reference is (L_ref[k] - L_ref[k-1]) / dt and the reported rate is v + a dt/2 (the caller
builds these references, see emulation.servo_references). Gains: per leg kp = m_i w^2, kv = 2 zeta m_i w
with m_i = 1/G_ii at the start pose (the leg's effective mass) and w = 2 pi bandwidth.

External load (``load_body``, e.g. the soft tissue on the platform): the caller sets that body's
``xfrc_applied`` before planning a block and keeps it over the block. Its part of b is S W (S: the leg
accelerations per unit of the body's xfrc_applied, refreshed with G): it is taken out of b before the
extrapolation and the block's own W put back, so a load that changes from block to block (a stiff
tissue at 35 Hz) is fed forward exactly instead of being extrapolated (which misses ~10 % of its change
per block at 35 Hz) -- the struts follow their references as stiff position actuators do.
"""

from __future__ import annotations

from typing import cast

import mujoco
import numpy as np

from ..sim.mujoco_sim import StewartSim


class ServoDrive:
    """PD servos (in MuJoCo) with a block-wise computed-force feedforward on a StewartSim."""

    _last_base: tuple[float, np.ndarray] | None
    _last_step: tuple[float, np.ndarray, np.ndarray] | None

    def __init__(self, sim: StewartSim, bandwidth_hz: float = 10.0, damping_ratio: float = 1.0,
                 gain_interval: int = 10, load_body: int | None = None):
        self.sim = sim
        self.load_body = load_body
        self._load_gain = np.zeros((6, 6))  # S: leg accelerations per unit xfrc_applied of load_body
        self._run_load = np.zeros(6)  # the load_body's xfrc_applied during the last run()
        self.model, self.data = sim.model, sim.data
        self.slide_q, self.slide_v = sim.slide_qpos, sim.slide_dof
        self.gain_interval = max(int(gain_interval), 1)
        self.kp = np.zeros(6)
        self.kv = np.zeros(6)
        self._apply_gains()
        base = self._zero_force_accel()
        mass = 1.0 / np.diag(self._sensitivity(base))
        omega = 2.0 * np.pi * bandwidth_hz
        self.kp, self.kv = mass * omega**2, mass * 2.0 * damping_ratio * omega
        self._apply_gains()
        self._inverse_gain: np.ndarray | None = None
        self._gain_age = 0
        self._last_base = None  # (time, b) of the previous block, for the extrapolation
        self._steps: np.ndarray = np.zeros((0, 1))
        self._gain: np.ndarray | None = None
        self._last_step = None  # (start time, leg accelerations, forces) of the last step
        self.last_accel = np.zeros(6)  # leg accelerations of the last step (m/s^2)
        self._accel_before = np.zeros(6)  # ... and of the step before it

    def restart(self) -> None:
        """Forget the previous blocks (after the state was set from outside): the next plan refreshes the gains
        and evaluates b directly."""
        self._inverse_gain, self._last_base, self._last_step = None, None, None
        self.last_accel = np.zeros(6)
        self._accel_before = np.zeros(6)

    def _apply_gains(self) -> None:
        self.model.actuator_biasprm[:6, 0] = 0.0
        self.model.actuator_biasprm[:6, 1] = -self.kp
        self.model.actuator_biasprm[:6, 2] = -self.kv

    @property
    def dt(self) -> float:
        """The physics step (s)."""
        return float(self.model.opt.timestep)

    def lengths(self) -> np.ndarray:
        """Total hinge-to-hinge leg lengths (6,) at the current time (m)."""
        return self.data.qpos[self.slide_q].copy()

    def rates(self) -> np.ndarray:
        """Leg length rates at the current time (m/s). Semi-implicit Euler moves the positions with the stored
        velocity v = (L_k+1 - L_k) / dt, so by Taylor the rate at t_k+1 is v + dt a / 2 - dt^2 j / 6 there; with
        a(t_k+1) = a_k + dt j and j = (a_k - a_k-1) / dt from the last two steps: v + dt (5 a_k - 2 a_k-1) / 6
        (v + dt a_k / 2 alone left 0.6 mm/s of a 120 Hz vibration in the strut rates)."""
        return self.data.qvel[self.slide_v] + self.dt * (5.0 * self.last_accel - 2.0 * self._accel_before) / 6.0

    def _zero_force_accel(self) -> np.ndarray:
        """Leg accelerations with zero actuator force at the current state (runs mj_forward)."""
        d = self.data
        d.ctrl[:6] = self.kp * d.qpos[self.slide_q] + self.kv * d.qvel[self.slide_v]
        mujoco.mj_forward(self.model, d)
        return d.qacc[self.slide_v].copy()

    def _sensitivity(self, base: np.ndarray) -> np.ndarray:
        """G = d L_ddot / d F (6, 6) at the current state (positions and velocities unchanged)."""
        d = self.data
        zero = d.ctrl[:6].copy()
        gain = np.empty((6, 6))
        for k in range(6):
            d.ctrl[:6] = zero
            d.ctrl[k] += 1.0
            mujoco.mj_forwardSkip(self.model, d, mujoco.mjtStage.mjSTAGE_VEL, 1)
            gain[:, k] = d.qacc[self.slide_v] - base
        d.ctrl[:6] = zero
        return gain

    def _load_sensitivity(self, base: np.ndarray) -> np.ndarray:
        """S = d L_ddot / d xfrc_applied[load_body] (6, 6) at the current state (controls at zero force)."""
        d, body = self.data, self.load_body
        load = d.xfrc_applied[body].copy()
        gain = np.empty((6, 6))
        for k in range(6):
            d.xfrc_applied[body] = load
            d.xfrc_applied[body, k] += 1.0
            mujoco.mj_forwardSkip(self.model, d, mujoco.mjtStage.mjSTAGE_VEL, 1)
            gain[:, k] = d.qacc[self.slide_v] - base
        d.xfrc_applied[body] = load
        return gain

    def plan(self, time: float, lengths, rates_half_back, accels, vib=None) -> np.ndarray:
        """Controls [n, 6] for the next n steps from ``time`` (s): reference lengths (m), rates half a step
        back (m/s) and step accelerations (m/s^2), each [n, 6] (``vib``, the unit demands, is already in
        the lengths: the units are part of the slides here).

        b comes for free from the last step (b = L_ddot - G F at that step's start: MuJoCo's
        accelerations are affine in the forces) and is extrapolated linearly over the block from the
        previous block's value; every ``gain_interval`` blocks G is refreshed and b evaluated directly
        (one mj_forward and six partial ones)."""
        refresh = self._inverse_gain is None or self._gain_age >= self.gain_interval or self._last_step is None
        load = self.data.xfrc_applied[self.load_body].copy() if self.load_body is not None else None
        if refresh:
            base = self._zero_force_accel()
            self._gain = self._sensitivity(base)
            self._inverse_gain = np.linalg.inv(self._gain)
            self._gain_age = 0
            at = time
            if load is not None:
                self._load_gain = self._load_sensitivity(base)
                base = base - self._load_gain @ load  # the load's part, put back below for this block
        else:  # no refresh: the gains and the last step are set
            step_time, step_accel, step_force = cast("tuple[float, np.ndarray, np.ndarray]", self._last_step)
            base = step_accel - self._gain @ step_force
            at = step_time
            if load is not None:
                base = base - self._load_gain @ self._run_load
        self._gain_age += 1
        n = len(lengths)
        if self._steps.shape[0] != n:
            self._steps = np.arange(n)[:, None] * self.dt
        previous = self._last_base
        self._last_base = (at, base)
        estimate = base
        if previous is not None and 0 < at - previous[0] < 0.05:
            estimate = base + (time - at + self._steps) * ((base - previous[1]) / (at - previous[0]))
        if load is not None:
            estimate = estimate + self._load_gain @ load
        feedforward = (accels - estimate) @ cast(np.ndarray, self._inverse_gain).T
        return feedforward + self.kp * lengths + self.kv * rates_half_back

    def first_force(self, controls: np.ndarray) -> np.ndarray:
        """Axial forces (6,) (N) the first planned step applies from the current state."""
        return controls[0] - self.kp * self.data.qpos[self.slide_q] - self.kv * self.data.qvel[self.slide_v]

    def run(self, controls: np.ndarray) -> None:
        """One physics step per row of ``controls`` [n, 6]."""
        m, d = self.model, self.data
        if self.load_body is not None:
            self._run_load = d.xfrc_applied[self.load_body].copy()
        ctrl, step = d.ctrl, mujoco.mj_step
        for row in controls[:-1]:
            ctrl[:] = row
            step(m, d)
        self._accel_before = d.qacc[self.slide_v].copy() if len(controls) > 1 else self.last_accel
        ctrl[:] = controls[-1]
        step(m, d)
        self.last_accel = d.qacc[self.slide_v].copy()
        # acceleration and force of the last step, at its start time (for b without an mj_forward)
        self._last_step = (d.time - self.dt, self.last_accel, d.actuator_force[:6].copy())
