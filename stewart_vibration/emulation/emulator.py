"""The emulated robot (no rclpy): MuJoCo model + strut servos + strut trajectory follower +
vibration command buffer + safety. The hardware_emulator node only converts messages.

Each leg is strut + vibration unit in series: the simulated slide is the total hinge-to-hinge
length; the joint state reports leg_i = total - vib_i (strut) and vib_i (the unit's displacement),
both with the same axial force.

Stepping: ``advance(duration)`` runs one block of physics steps (the state period, e.g. 2 ms = 4
steps at 2 kHz) with controls planned for the whole block (``servo_drive``); the references of the
strut trajectory and the vibration buffer are sampled for ``reference_horizon_s`` at a time in one
vectorised call and reused until a command changes them.

Soft tissue (optional ``tissue``, a ``stewart_vibration.dynamics.tissue.TissueModel``): its wrench is evaluated
from the platform's state at the start of every block and applied over the block as MuJoCo's
``xfrc_applied`` on the platform body (force at the body's centre of mass and the moment about it,
world frame: the tissue's moment about the platform origin minus (R c_m) x F). ``tissue_wrench``
holds the wrench applied from the current time (about the platform origin, base frame). The struts are
leadscrew actuators, stiff position sources: the servos' feedforward takes the applied load in exactly
(servo_drive ``load_body``), so the tissue changes the strut forces, not the motion.
"""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np

from ..dynamics.tissue import TissueModel, tissue_wrench_single
from ..errors import ActuatorLimitError
from ..kinematics import inverse_kinematics
from ..motion.profiles import minimum_jerk, minimum_jerk_duration
from ..robot import LEG_NAMES, VIB_NAMES, Robot
from ..sim.mjcf import SimulationSettings
from ..sim.mujoco_sim import StewartSim
from .servo_drive import ServoDrive
from .strut_trajectory import (
    MAX_START_DELAY_S,
    STEP_SPEED,
    JointTrajectory,
    TrajectoryFollower,
    build_trajectory,
    checked_command,
    controlled_stop,
)
from .vibration_buffer import VibrationBuffer
from .vibration_status import EMERGENCY_STOP, VibrationReport, VibrationStatusTracker


class HardwareEmulator:
    """Step the robot in MuJoCo while following strut and vibration commands safely.

    Time is simulation time (s, starts at 0). Commands take effect from the next block.
    """

    _refs: tuple[int, float, tuple[np.ndarray, ...]] | None
    _planned: tuple[int, float, np.ndarray] | None

    def __init__(self, robot: Robot, settings: SimulationSettings, watchdog_s: float = 0.5,
                 vibration_ramp_s: float = 0.05, gain_interval: int = 10, max_lookahead_s: float = 30.0,
                 reference_horizon_s: float = 0.05, max_start_delay_s: float = MAX_START_DELAY_S,
                 tissue: TissueModel | None = None):
        self.robot = robot
        self.max_start_delay_s = float(max_start_delay_s)
        self.sim = StewartSim(robot, replace(settings, integrator=settings.emulator_integrator))
        self.sim.reset(robot.home_pose)
        self.tissue = tissue
        self.tissue_wrench = np.zeros(6)  # applied from the current time on (N, N m about the platform origin)
        self._platform_body = self.sim.model.body("platform").id
        self._com = robot.moving_body.com.tolist()
        self._rot = np.zeros(9)
        self._apply_tissue()
        self.drive = ServoDrive(self.sim, settings.servo_bandwidth_hz, settings.drive_damping_ratio, gain_interval,
                                load_body=self._platform_body if tissue is not None else None)
        self.home_lengths = inverse_kinematics(robot, robot.home_pose)
        self.struts = TrajectoryFollower(self.home_lengths)
        self.vibration = VibrationBuffer(robot.vibration_unit, watchdog_s, vibration_ramp_s, max_lookahead_s)
        self.status = VibrationStatusTracker()
        self.forces = np.zeros(6)
        self.estopped = False
        self.reference_horizon_s = float(reference_horizon_s)
        self._version = 0  # bumped by every accepted command: cached references and planned controls are stale
        self._refs = None  # (version, first step time, arrays) of the sampled references
        self._planned = None  # (version, time, controls) for the block starting at ``time``

    @property
    def time(self) -> float:
        """Simulation time now (s, 0 at start)."""
        return self.sim.time

    @property
    def dt(self) -> float:
        """The physics step (s)."""
        return float(self.sim.model.opt.timestep)

    # -- commands ----------------------------------------------------------------
    def command_struts(self, names, start, times, positions, velocities=None, accelerations=None) -> JointTrajectory:
        """Validate and run a leg_* trajectory (replaces the running one); returns it as it runs.

        joint_trajectory_controller rules with the limits enforced on what will actually be followed:
        start 0 = now; points already in the past are dropped and the motion departs from the state
        commanded now toward the first future point; a trajectory with positions only gets
        finite-difference velocities (zero at its first and last point) and cubic segments instead of
        linear ones (a linear one steps the velocity at every point). The spline from the departure
        state through every point must stay within the stroke, strut_velocity_max and
        strut_acceleration_max and end at rest (the last point is held); a start more than
        ``max_start_delay_s`` ahead, or one in the future while another still waits for its start, is refused. Until
        a future start the running command goes on (``trajectory.checked_command``). Raises
        InvalidInputError, StrokeLimitError or ActuatorLimitError with the reason; nothing moves then.
        """
        if self.estopped:
            raise ActuatorLimitError("emergency stop is active: call reset first", limit_name="emergency_stop")
        traj = build_trajectory(names, LEG_NAMES, start, times, positions, velocities, accelerations)
        running = checked_command(self.struts, traj, self.time, self.robot.limits, self.max_start_delay_s,
                                  STEP_SPEED * self.robot.limits.strut_acceleration_max * self.dt)
        self._changed()
        return self.struts.replace(running, self.time)

    def command_vibration(self, names, start, times, positions, velocities=None, accelerations=None) -> float:
        """Validate and splice a vib_* window onto the buffer; returns the splice time (s). Raises
        InvalidInputError / VibrationLimitError / ActuatorLimitError (e-stop active) with the reason;
        the refusal is also recorded in the vibration status."""
        now = self.time
        try:
            if self.estopped:
                raise ActuatorLimitError("emergency stop is active: call hardware_emulator/reset first",
                                         limit_name="emergency_stop")
            traj = build_trajectory(names, VIB_NAMES, start, times, positions, velocities, accelerations)
            splice = self.vibration.add(traj, now)
        except Exception as exc:
            self.status.refused(now, float(start), str(exc))
            raise
        self.status.accepted(now, float(start))
        self._changed()
        return splice

    def emergency_stop(self) -> None:
        """Ramp the vibration to zero and bring the struts to rest within strut_acceleration_max (a controlled
        stop from the state commanded now, see ``controlled_stop``), then hold; latched until reset()."""
        now = self.time
        self.vibration.stop(now, EMERGENCY_STOP)
        if not self.estopped:
            stop = controlled_stop(self.struts, now, self.robot.limits.strut_acceleration_max)
            if stop is None:
                self.struts.hold(self.struts.sample([now])[0][0])
            else:
                self.struts.replace(stop, now)
        if not self.estopped:
            self.status.safety_ramp(now, EMERGENCY_STOP)
        self.estopped = True
        self._changed()

    def reset(self) -> float:
        """Clear a latched e-stop and move smoothly home; returns the move's duration (s).

        Raises ActuatorLimitError (limit_name "reset") when no e-stop is latched: reset moves the
        robot, so it only acts as the way out of an e-stop."""
        if not self.estopped:
            raise ActuatorLimitError("no emergency stop is latched: reset only clears an e-stop (it moves the "
                                     "robot home)", limit_name="reset")
        now = self.time
        self.estopped = False
        current = self.struts.sample([now])[0][0]
        duration = minimum_jerk_duration(current, self.home_lengths, 0.5 * self.robot.limits.strut_velocity_max, 0.5)
        times = np.linspace(duration / 50, duration, 50)
        pos, vel, acc = minimum_jerk(current, self.home_lengths, duration, times)
        self.struts.hold(current)
        self.struts.replace(build_trajectory(LEG_NAMES, LEG_NAMES, 0.0, times, pos, vel, acc), now)
        self._changed()
        return duration

    def _changed(self) -> None:
        self._version += 1

    def _apply_tissue(self) -> None:
        """Evaluate the tissue wrench at the current state and apply it until the next call (xfrc_applied)."""
        if self.tissue is None:
            return
        sim, data = self.sim, self.sim.data
        q = data.qpos[sim.free_qpos:sim.free_qpos + 7]
        qv = data.qvel[sim.free_dof:sim.free_dof + 6]
        mujoco.mju_quat2Mat(self._rot, q[3:7])
        rot = self._rot.reshape(3, 3)
        omega = (rot @ qv[3:6]).tolist()  # MuJoCo keeps the free joint's angular velocity in the body frame
        w = tissue_wrench_single(self.tissue, q[:3].tolist(), rot, qv[:3].tolist(), omega)
        cx, cy, cz = self._com
        (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = rot.tolist()
        ax, ay, az = r00 * cx + r01 * cy + r02 * cz, r10 * cx + r11 * cy + r12 * cz, r20 * cx + r21 * cy + r22 * cz
        fx, fy, fz = w[0], w[1], w[2]
        # xfrc_applied: force at the centre of mass, moment about it (world frame)
        data.xfrc_applied[self._platform_body] = (fx, fy, fz, w[3] - (ay * fz - az * fy), w[4] - (az * fx - ax * fz),
                                                  w[5] - (ax * fy - ay * fx))
        self.tissue_wrench = np.array(w)

    # -- stepping ----------------------------------------------------------------
    def _references(self, time: float, steps: int):
        """(lengths, rates at t - dt/2, accelerations, vib positions, vib velocities) [steps + 1, 6] at the
        step times time + k dt, k = 0..steps (the last row is the block's end), from the cache.

        The servos' references come from the commanded hinge lengths L (strut + vibration) on the step
        grid: the acceleration of step k is the second difference (L[k+1] - 2 L[k] + L[k-1]) / dt^2 and
        the rate (L[k] - L[k-1]) / dt, the values with which semi-implicit Euler reproduces L at every
        step (its velocities live half a step back)."""
        dt = self.dt
        cache = self._refs
        if cache is not None and cache[0] == self._version:
            first = int(round((time - cache[1]) / dt))
            if 0 <= first and first + steps < len(cache[2][0]):
                return tuple(a[first:first + steps + 1] for a in cache[2])
        count = max(steps, int(round(self.reference_horizon_s / dt))) + 1
        t = time + dt * np.arange(-1, count + 1)  # one step before and after for the differences
        strut = self.struts.sample(t)[0]
        vib, vib_rate, _ = self.vibration.sample(t)
        length = strut + vib
        accel = (length[2:] - 2.0 * length[1:-1] + length[:-2]) / dt**2
        rates_half = (length[1:-1] - length[:-2]) / dt
        arrays = (length[1:-1], rates_half, accel, vib[1:-1], vib_rate[1:-1])
        self._refs = (self._version, time, arrays)
        return tuple(a[:steps + 1] for a in arrays)

    def _controls(self, time: float, steps: int) -> np.ndarray:
        planned = self._planned
        if planned is not None and planned[0] == self._version and planned[1] == time and len(planned[2]) == steps:
            return planned[2]
        lengths, rates_half, accels, _, _ = self._references(time, steps)
        return self.drive.plan(time, lengths[:steps], rates_half[:steps], accels[:steps])

    def advance(self, duration: float) -> int:
        """Run round(duration / dt) physics steps as one block; returns the number of steps.

        Afterwards ``forces`` holds the axial forces at the new time: those of the step that starts
        there (the next block's controls are planned now and reused if no command arrives).
        """
        steps = max(int(round(duration / self.dt)), 1)
        self.drive.run(self._controls(self.time, steps))
        self._apply_tissue()  # the tissue's wrench over the next block, from the state now
        now = self.time
        controls = self._controls(now, steps)
        self._planned = (self._version, now, controls)
        self.forces = self.drive.first_force(controls)
        return steps

    # -- read-back ---------------------------------------------------------------
    def joint_state(self):
        """(names, positions, velocities, efforts) for leg_1..6, vib_1..6 at the current time."""
        total, rate = self.drive.lengths(), self.drive.rates()
        _, _, _, vib, vib_rate = self._references(self.time, 0)
        vib, vib_rate = vib[0], vib_rate[0]
        positions = np.concatenate([total - vib, vib])
        velocities = np.concatenate([rate - vib_rate, vib_rate])
        efforts = np.concatenate([self.forces, self.forces])
        return LEG_NAMES + VIB_NAMES, positions, velocities, efforts

    def platform_pose(self) -> np.ndarray:
        """The platform's ground-truth pose (6,) [x, y, z, roll, pitch, yaw] (m, rad) in the base frame."""
        return self.sim.platform_pose()

    def vibration_report(self) -> tuple[VibrationReport, bool]:
        """(report, state changed) of what the vibration units do now (see vibration_status)."""
        return self.status.update(self.vibration.status(self.time), self.estopped, self.time)
