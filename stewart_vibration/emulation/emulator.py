"""The emulated robot (no rclpy): MuJoCo model + strut trajectory follower +
vibration buffer + safety. The hardware_emulator node only converts messages.

Each leg is strut + vibration unit in series: the simulated slide is the total
hinge-to-hinge length; the joint state reports leg_i = total - vib_i (strut)
and vib_i (the unit's displacement), both with the same axial force.
"""

from __future__ import annotations

import numpy as np

from ..errors import ActuatorLimitError, StrokeLimitError
from ..kinematics import inverse_kinematics
from ..mjcf import SimulationSettings
from ..motion_profiles import minimum_jerk, minimum_jerk_duration
from ..mujoco_sim import StewartSim
from ..robot import Robot
from .trajectory import JointTrajectory, TrajectoryFollower, build_trajectory
from .vibration_buffer import VibrationBuffer

LEG_NAMES = [f"leg_{i}" for i in range(1, 7)]
VIB_NAMES = [f"vib_{i}" for i in range(1, 7)]
SPEED_TOLERANCE = 1.0 + 1e-6


class HardwareEmulator:
    """Step the robot in MuJoCo while following strut and vibration commands safely.

    Time is simulation time (s, starts at 0). ``advance(duration)`` runs whole
    physics steps; commands are sampled at each step's start time.
    """

    def __init__(self, robot: Robot, settings: SimulationSettings, watchdog_s: float = 0.5,
                 vibration_ramp_s: float = 0.05, gain_interval: int = 1):
        self.robot = robot
        # gain_interval: steps between recomputations of the drive's 6x6 force-to-acceleration map
        # (six extra mj_forward calls each); the map barely changes over a few ms of motion
        self.sim = StewartSim(robot, settings, gain_interval=gain_interval)
        self.sim.reset(robot.home_pose)
        self.home_lengths = inverse_kinematics(robot, robot.home_pose)
        self.struts = TrajectoryFollower(self.home_lengths)
        self.vibration = VibrationBuffer(robot.vibration_unit, watchdog_s, vibration_ramp_s)
        self.forces = np.zeros(6)
        self.estopped = False
        self._version = 0  # bumped by every accepted command: the cached next-step forces are stale then
        self._pending_time = None
        self._pending_version = -1
        self._next_forces = np.zeros(6)

    @property
    def time(self) -> float:
        return self.sim.time

    @property
    def dt(self) -> float:
        return float(self.sim.model.opt.timestep)

    # -- commands ----------------------------------------------------------------
    def command_struts(self, names, start, times, positions, velocities=None, accelerations=None) -> JointTrajectory:
        """Validate and run a leg_* trajectory (replaces the running one). Raises InvalidInputError,
        StrokeLimitError or ActuatorLimitError with the reason; nothing moves then."""
        if self.estopped:
            raise ActuatorLimitError("emergency stop is active: call reset first", limit_name="emergency_stop")
        traj = build_trajectory(names, LEG_NAMES, start, times, positions, velocities, accelerations)
        self._check_strut_limits(traj)
        self._version += 1
        return self.struts.replace(traj, self.time)

    def _check_strut_limits(self, traj: JointTrajectory) -> None:
        lim = self.robot.limits
        for bad, limit, word in ((traj.positions < lim.stroke_min, lim.stroke_min, "below"),
                                 (traj.positions > lim.stroke_max, lim.stroke_max, "above")):
            if bad.any():
                point, leg = np.argwhere(bad)[0]
                value = float(traj.positions[point, leg])
                raise StrokeLimitError(
                    f"leg_{leg + 1} point {point}: {value:.6f} m is {word} the stroke limit {limit:.6f} m",
                    leg=int(leg) + 1, value=value, limit=limit)
        start = self.time if traj.start <= 0 else traj.start
        departure = self.struts.sample([start])[0][0]
        knots_t = np.concatenate([[0.0], traj.times])
        knots_p = np.vstack([departure, traj.positions])
        dt = np.diff(knots_t)
        speeds = np.abs(np.diff(knots_p, axis=0)) / np.where(dt > 0, dt, np.inf)[:, None]
        if dt[0] == 0 and np.abs(knots_p[1] - knots_p[0]).max() > 1e-9:
            speeds[0] = np.inf  # a jump at the start time
        if traj.velocities is not None:
            speeds = np.vstack([speeds, np.abs(traj.velocities)])
        peak = speeds.max(axis=0)
        if (peak > lim.strut_velocity_max * SPEED_TOLERANCE).any():
            leg = int(np.argmax(peak))
            raise ActuatorLimitError(
                f"leg_{leg + 1}: speed {peak[leg]:.4g} m/s exceeds strut_velocity_max "
                f"{lim.strut_velocity_max:.4g} m/s", leg=leg + 1, limit_name="strut_velocity_max",
                value=float(peak[leg]), limit=lim.strut_velocity_max)

    def command_vibration(self, names, start, times, positions, velocities=None) -> None:
        """Validate and buffer a vib_* window. Raises InvalidInputError / VibrationLimitError /
        ActuatorLimitError (e-stop active) with the reason."""
        if self.estopped:
            raise ActuatorLimitError("emergency stop is active: call reset first", limit_name="emergency_stop")
        traj = build_trajectory(names, VIB_NAMES, start, times, positions, velocities)
        self.vibration.add(traj, self.time)
        self._version += 1

    def emergency_stop(self) -> None:
        """Ramp the vibration to zero and hold the strut lengths commanded now; latched until reset()."""
        now = self.time
        self.vibration.stop(now, "emergency stop")
        self.struts.hold(self.struts.sample([now])[0][0])
        self.estopped = True
        self._version += 1

    def reset(self) -> float:
        """Clear the e-stop, ramp any vibration out, and move smoothly home; returns the move's duration (s)."""
        now = self.time
        self.vibration.stop(now, "reset")
        self.estopped = False
        current = self.struts.sample([now])[0][0]
        duration = minimum_jerk_duration(current, self.home_lengths, 0.5 * self.robot.limits.strut_velocity_max, 0.5)
        times = np.linspace(duration / 50, duration, 50)
        pos, vel, acc = minimum_jerk(current, self.home_lengths, duration, times)
        self.struts.hold(current)
        self.struts.replace(build_trajectory(LEG_NAMES, LEG_NAMES, 0.0, times, pos, vel, acc), now)
        self._version += 1
        return duration

    # -- stepping ----------------------------------------------------------------
    def advance(self, duration: float) -> int:
        """Run round(duration / dt) physics steps; returns the number of steps.

        Afterwards ``forces`` holds the axial forces at the new time (interpolated from the
        step forces, see below); the next step's forces are computed once and reused.
        """
        steps = max(int(round(duration / self.dt)), 1)
        t = self.time + self.dt * np.arange(steps + 1)
        # positions/rates at each step start (the drive's feedback); the feedforward acceleration at the
        # step midpoint, because the force is held over the step (sampling it at the start delays it by
        # dt/2: a 3 % amplitude error at 35 Hz with 1 ms steps)
        p, v, _ = self.struts.sample(t)
        a = self.struts.sample(t + 0.5 * self.dt)[2]
        vp, vv, _ = self.vibration.sample(t)
        va = self.vibration.sample(t + 0.5 * self.dt)[2]
        length, rate, accel = p + vp, v + vv, a + va
        for k in range(steps):
            if k == 0 and self._pending_time == self.time and self._pending_version == self._version:
                forces = self._next_forces
            else:
                forces = self.sim.drive_forces(length[k], rate[k], accel[k])
            self.sim.step(forces)
        self._next_forces = self.sim.drive_forces(length[steps], rate[steps], accel[steps])
        self._pending_time, self._pending_version = self.time, self._version
        # Each force is held over one step and aims at the acceleration at that step's midpoint, so the
        # last and the next are samples of the continuous axial force at t - dt/2 and t + dt/2; their
        # mean is the force at t (what a load cell reads) to second order: a sinusoid's amplitude is
        # read cos(w dt / 2) low (0.15 % at 35 Hz, 2 kHz). Higher-order interpolation was tried and
        # amplifies the drive's step-to-step jitter.
        self.forces = 0.5 * (forces + self._next_forces)
        return steps

    # -- read-back ---------------------------------------------------------------
    def joint_state(self):
        """(names, positions, velocities, efforts) for leg_1..6, vib_1..6 at the current time."""
        total, rate = self.sim.leg_lengths(), self.sim.leg_velocities()
        vib, vib_rate, _ = self.vibration.sample([self.time])
        vib, vib_rate = vib[0], vib_rate[0]
        positions = np.concatenate([total - vib, vib])
        velocities = np.concatenate([rate - vib_rate, vib_rate])
        efforts = np.concatenate([self.forces, self.forces])
        return LEG_NAMES + VIB_NAMES, positions, velocities, efforts

    def platform_pose(self) -> np.ndarray:
        return self.sim.platform_pose()
