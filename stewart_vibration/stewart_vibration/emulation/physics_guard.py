"""The emulator's divergence detector (no rclpy): physics that can never publish nonsense.

Checked once per block of physics steps, against what the emulated robot can do, with a handful of vector
reductions (~10 us a block, against ~600 us of physics): every qpos / qvel finite; the six leg-to-platform
connect constraints closed within CONSTRAINT_MAX_M; every strut within FOLLOWING_ERROR_MAX_M of its
commanded length (a drive's following-error fault); the generalised velocity |qvel| within SPEED_MAX and not
jumping by more than SPEED_JUMP within a block; and, every WARNING_EVERY blocks, no new MuJoCo warning (bad
qacc / qpos / qvel, inertia, full constraint buffers; a bad acceleration leaves a huge or non-finite velocity
that the checks above see at once). Normal running is orders of magnitude inside each bound (measured at the
paper's pose with a 49 Hz / 0.9 g vibration: connect gap 8e-9 m, following error 2e-7 m, |qvel| 0.15).

MuJoCo itself answers a non-finite or huge acceleration (mj_checkAcc, also mj_checkPos / mj_checkVel) by
raising mjWARN_BADQACC and calling mj_resetData -- qpos back to the model's reference and *time back to 0*
-- unless the model's disableflags carry mjDSBL_AUTORESET. The guard sets that flag, so MuJoCo only warns;
the guard sees the warning (or the non-finite state it leaves) and latches a ``PhysicsFault``: the last good
state is restored at rest and held, and time goes on from where it was (it never goes back within a run).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

CONSTRAINT_MAX_M = 1e-4  # leg-to-platform connect gap, 2-norm over the six (m)
FOLLOWING_ERROR_MAX_M = 1e-3  # strut length against its reference (m)
SPEED_MAX = 20.0  # |qvel|, 2-norm of every generalised velocity (m/s and rad/s)
SPEED_JUMP = 10.0  # |qvel| may grow by at most this factor (plus SPEED_FLOOR) within a block
SPEED_FLOOR = 0.5
WARNING_EVERY = 25  # blocks between reads of MuJoCo's warning counters
WATCHED_WARNINGS = (mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQPOS,
                    mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADCTRL,
                    mujoco.mjtWarning.mjWARN_INERTIA, mujoco.mjtWarning.mjWARN_CNSTRFULL,
                    mujoco.mjtWarning.mjWARN_CONTACTFULL)


@dataclass(frozen=True)
class PhysicsFault:
    """A latched divergence: sim ``time`` (s) of the block where it was seen and the ``reason``."""

    time: float
    reason: str


class PhysicsGuard:
    """Snapshot / check / restore of one MuJoCo model + data (see the module docstring)."""

    def __init__(self, model, data, slide_qpos, slide_dof):
        self.model, self.data = model, data
        model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
        self.slide_qpos, self.slide_dof = np.asarray(slide_qpos), np.asarray(slide_dof)
        self._good_qpos = data.qpos.copy()
        self._good_time = float(data.time)
        self._speed = 0.0
        self._blocks = 0
        self._warnings = self._warning_count()

    def _warning_count(self) -> int:
        return sum(int(self.data.warning[w].number) for w in WATCHED_WARNINGS)

    def check(self, reference_lengths) -> str | None:
        """Why the state after a block is not physical (the first failing check), or None (then it becomes the
        last good state). ``reference_lengths``: the commanded strut (+ vibration) lengths (6,) now (m).
        Scalars in plain floats and a few vector reductions: it runs once per block."""
        d = self.data
        qpos, qvel = d.qpos, d.qvel
        speed2 = float(qvel.dot(qvel))
        if not (math.isfinite(speed2) and math.isfinite(float(qpos.dot(qpos)))):
            return "non-finite joint positions or velocities"
        now = float(d.time)
        if now < self._good_time:
            return f"sim time went back from {self._good_time:.6f} s to {now:.6f} s"
        self._blocks += 1
        if self._blocks % WARNING_EVERY == 0:
            warnings = self._warning_count()
            if warnings != self._warnings:
                self._warnings = warnings
                names = [w.name for w in WATCHED_WARNINGS if d.warning[w].number]
                return f"MuJoCo warning {', '.join(names)}: the simulation is unstable"
        nefc = d.nefc
        if nefc:
            gap = d.efc_pos[:nefc]
            gap2 = float(gap.dot(gap))
            if not gap2 <= CONSTRAINT_MAX_M**2:
                return (f"the leg-to-platform joints opened by {math.sqrt(gap2) * 1e3:.3f} mm (limit "
                        f"{CONSTRAINT_MAX_M * 1e3:g} mm)")
        error = qpos[self.slide_qpos]
        error -= reference_lengths
        worst = float(np.abs(error, out=error).max())
        if not worst <= FOLLOWING_ERROR_MAX_M:
            return (f"strut following error {worst * 1e3:.3f} mm (limit {FOLLOWING_ERROR_MAX_M * 1e3:g} mm): the "
                    "struts no longer follow their commands")
        speed = math.sqrt(speed2)
        if speed > SPEED_MAX or speed > SPEED_JUMP * self._speed + SPEED_FLOOR:
            return (f"the joint velocities jumped from |qvel| {self._speed:.3g} to {speed:.3g} within a block (limit "
                    f"{SPEED_MAX:g})")
        self._speed = speed
        self._good_qpos[:] = qpos
        self._good_time = now
        return None

    def hold(self, time: float) -> None:
        """Put the last good positions back, at rest, at sim time ``time`` (s, never earlier than the last good
        state's), and recompute the derived quantities."""
        d = self.data
        d.qpos[:] = self._good_qpos
        d.qvel[:] = 0.0
        d.qacc[:] = 0.0
        d.qacc_warmstart[:] = 0.0
        d.ctrl[:6] = -self.model.actuator_biasprm[:6, 1] * d.qpos[self.slide_qpos]  # the servos' force 0 (finite)
        d.xfrc_applied[:] = 0.0
        d.time = max(float(time), self._good_time)
        mujoco.mj_forward(self.model, d)
