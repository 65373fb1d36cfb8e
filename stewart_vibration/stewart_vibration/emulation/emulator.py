"""The emulated robot (no rclpy): MuJoCo model + strut servos + the robot's safety layer (``safety_controller``:
strut trajectory follower, vibration command buffer, every command check and stop; its commands at the
emulator's time: ``emulator_commands``) + the divergence detector (``physics_guard``). The hardware_emulator
node only converts messages.

Each leg is strut + vibration unit in series: the simulated slide is the total hinge-to-hinge
length; the joint state reports leg_i = total - vib_i (strut) and vib_i (the unit's displacement),
both with the same axial force.

Stepping: ``advance(duration)`` runs one block of physics steps (the state period, e.g. 2 ms = 4
steps at 2 kHz) with controls planned for the whole block (``servo_drive``); the references of the
strut trajectory and the vibration buffer are sampled for ``reference_horizon_s`` at a time in one
vectorised call and reused until a command changes them (``servo_references``).

Soft tissue (optional ``tissue``, a ``stewart_vibration.dynamics.tissue.TissueModel``): its wrench is applied
to the platform over every block (``tissue_load``); ``tissue_wrench`` holds the wrench applied from the
current time (about the platform origin, base frame). The struts are leadscrew actuators, stiff position
sources: the servos' feedforward takes the applied load in exactly (servo_drive ``load_body``), so the tissue
changes the strut forces, not the motion.

The robot as built (``plant``, an ``emulation.plant.Plant`` of kind "realistic"): MuJoCo runs the plant's
true geometry and payload with each vibration unit as a body of its own (mjcf ``UnitSliders``), and the
drives are the plant's (``plant_drive``): strut servos on their encoders, no feedforward from any model,
with friction, and each unit's own firmware and amplifier. The commands stay in the controller's frame
(encoder lengths, unit demands); the joint states report the sensors (encoders, unit sensors, load cells
with their noise and offsets); ``platform_pose`` stays the truth. Without a plant (or the ideal one) the
robot is the drawing, as above.
"""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np

from ..dynamics.tissue import TissueModel
from ..errors import ConfigError
from ..kinematics import check_pose
from ..kinematics.rotations import rotation_from_quaternion
from ..robot import LEG_NAMES, VIB_NAMES, Robot
from ..sim.mjcf import SimulationSettings, UnitSliders
from ..sim.mujoco_sim import StewartSim
from .emulator_commands import EmulatorCommands
from .physics_guard import PhysicsGuard
from .plant import Plant
from .plant_drive import PlantDrive
from .plant_readings import sensed_joint_state, true_joint_state, true_pose
from .platform_sensors import ImuSample, PlatformImu, PlatformTracker, TrackerFrame, specific_force
from .safety_controller import SafetyController
from .servo_drive import ServoDrive
from .servo_references import ServoReferences
from .strut_trajectory import MAX_START_DELAY_S
from .tissue_load import apply_tissue_wrench
from .unit_travel import UnitTravelGuard
from .vibration_unit import unit_hardware


class HardwareEmulator(EmulatorCommands):
    """Step the robot in MuJoCo while following strut and vibration commands safely.

    The commands and every safety rule live in ``safety``, a ``SafetyController`` (the robot's own safety
    layer; its commands and state: ``EmulatorCommands``); this class adds the physics: the MuJoCo model, the
    strut servos and the divergence detector (``physics_guard``). Time is simulation time (s, starts at
    ``start_time``, 0 unless the robot is built again within a run, and never goes back). Commands take effect
    from the next block.
    """

    _planned: tuple[int, float, np.ndarray] | None

    def __init__(self, robot: Robot, settings: SimulationSettings, watchdog_s: float = 0.5,
                 vibration_ramp_s: float = 0.05, gain_interval: int = 10, max_lookahead_s: float = 30.0,
                 reference_horizon_s: float = 0.05, max_start_delay_s: float = MAX_START_DELAY_S,
                 tissue: TissueModel | None = None, plant: Plant | None = None, sensor_rate_hz: float = 500.0,
                 start_time: float = 0.0):
        self.robot = robot
        self.plant = plant if plant is not None and plant.kind == "realistic" else None
        physics = replace(settings, integrator=settings.emulator_integrator)
        self.tissue = tissue
        self.tissue_wrench = np.zeros(6)  # applied from the current time on (N, N m about the platform origin)
        self._rot = np.zeros(9)
        built = robot if self.plant is None else self.plant.robot
        self._com = built.moving_body.com.tolist()
        self.drive: ServoDrive | PlantDrive
        if self.plant is None:
            self.sim = StewartSim(robot, physics)
            self.sim.reset(robot.home_pose)
            self._platform_body = self.sim.model.body("platform").id
            self._apply_tissue()
            self.drive = ServoDrive(self.sim, settings.servo_bandwidth_hz, settings.drive_damping_ratio,
                                    gain_interval, load_body=self._platform_body if tissue is not None else None)
        else:
            self._build_plant(self.plant, physics)
        # a robot built again within a run (lifecycle cleanup + configure) goes on from the run's clock: sim time
        # never goes back for the nodes, the logs and the replay
        self.sim.data.time = float(start_time)
        self.guard = PhysicsGuard(self.sim.model, self.sim.data, self.sim.slide_qpos, self.sim.slide_dof)
        self.safety = SafetyController(robot, self.dt, watchdog_s, vibration_ramp_s, max_lookahead_s,
                                       max_start_delay_s)
        self.travel = UnitTravelGuard(robot.vibration_unit.amplitude_max)
        self.forces = np.zeros(6)
        self.reference_horizon_s = float(reference_horizon_s)
        self.servo_references = ServoReferences(self.safety)
        self._planned = None  # (version, time, controls) for the block starting at ``time``
        self._build_platform_sensors(plant, sensor_rate_hz)

    def _build_platform_sensors(self, plant: Plant | None, rate_hz: float) -> None:
        """``imu`` and ``tracker``: the plant's (its noise, biases and latency, seeded from its seed), or
        noiseless ones without a plant."""
        self._imu_velocity: tuple[float, np.ndarray] | None = None  # (time s, platform velocity m/s), last IMU sample
        rng = np.random.default_rng(None if plant is None else [plant.seed, 0x5E5])
        if plant is None:
            self.imu, self.tracker = PlatformImu(rate_hz, rng=rng), PlatformTracker(60.0, rng=rng)
            return
        s = plant.sensors
        self.imu = PlatformImu(rate_hz, s.accel_noise_density, s.gyro_noise_density, s.accel_bias_m_s2,
                               s.gyro_bias_rad_s, rng=rng)
        self.tracker = PlatformTracker(s.tracker_rate_hz, s.tracker_position_noise_m,
                                       s.tracker_orientation_noise_deg, s.tracker_latency_s, rng=rng)

    def _build_plant(self, plant: Plant, physics: SimulationSettings) -> None:
        """``sim``: MuJoCo with the plant's geometry, payload and unit sliders at rest at home; ``drive``: the
        plant's drives."""
        if plant.units.model != "resonant" or plant.struts.model != "servo":
            raise ConfigError(f"plant config {plant.source}: a realistic plant needs vibration_units.model "
                              f"'resonant' and struts.model 'servo' (got {plant.units.model!r}, "
                              f"{plant.struts.model!r})")
        units = unit_hardware(plant.units, plant.robot.leg.vibration_unit_mass, float(physics.timestep))
        sliders = UnitSliders(units.moving_mass_kg, tuple(units.stiffness_n_m))
        self.sim = StewartSim(plant.robot, physics, units=sliders)
        self._platform_body = self.sim.model.body("platform").id
        self.sim.reset(true_pose(plant, check_pose(self.robot, self.robot.home_pose), self.robot.home_pose))
        self._apply_tissue()
        rigid = StewartSim(plant.robot, physics)
        rigid.reset(self.sim.platform_pose())
        self.drive = PlantDrive(self.sim, plant, units, plant.struts.bandwidth_hz, physics.drive_damping_ratio,
                                seed=plant.seed, rigid=rigid)
        self.drive.restart()

    @property
    def time(self) -> float:
        """Simulation time now (s, 0 at start)."""
        return self.sim.time

    @property
    def dt(self) -> float:
        """The physics step (s)."""
        return float(self.sim.model.opt.timestep)

    # -- the state set from outside (a fresh start, a fault) -----------------------------------
    def place_at_rest(self, pose=None) -> None:
        """Put the robot at rest at ``pose`` (m, rad; default home) now, a fresh start state for a bench or a test
        (not a command: nothing moves there, the state is set): the struts hold its lengths, the vibration
        buffer is emptied, a latched e-stop is cleared; time goes on. Raises PhysicsFaultError after a fault and
        the pose checks' errors (``check_pose``)."""
        pose = self.robot.home_pose if pose is None else np.asarray(pose, dtype=float)
        lengths = check_pose(self.robot, pose)
        self._imu_velocity = None  # the state is set, not reached: no acceleration across it
        self.safety.place_at_rest(lengths)
        if self.plant is None:
            self.sim.set_state(pose)
            self.drive.restart()
            self._apply_tissue()
            self.guard.check(lengths)  # the new last good state
            return
        assert isinstance(self.drive, PlantDrive)
        data = self.sim.data
        data.qpos[self.drive.vib_q], data.qvel[self.drive.vib_v] = 0.0, 0.0
        self.sim.set_state(true_pose(self.plant, lengths, pose))
        self._apply_tissue()
        self.drive.restart()
        self.guard.check(lengths + self.plant.strut_zero_offsets)

    def latch_fault(self, reason: str) -> None:
        """Latch a physics fault now (the divergence detector, or an exception in the physics thread): the last
        good state is held at rest, the vibration dropped, every command refused until the emulator is rebuilt;
        time goes on."""
        if self.fault is not None:
            return
        now = self.time
        self.guard.hold(now)
        self.drive.restart()  # at rest: no acceleration in the reported rates
        self.safety.latch_physics_fault(now, reason, self.drive.lengths())

    def _apply_tissue(self) -> None:
        """Evaluate the tissue wrench at the current state and apply it until the next call (xfrc_applied)."""
        if self.tissue is not None:
            self.tissue_wrench = apply_tissue_wrench(self.sim, self.tissue, self._platform_body, self._com, self._rot)

    # -- stepping ----------------------------------------------------------------
    def _references(self, time: float, steps: int):
        """The servos' references over the block of ``steps`` steps from ``time`` (``ServoReferences.sample``)."""
        return self.servo_references.sample(time, steps, self.dt, self.reference_horizon_s)

    def _controls(self, time: float, steps: int, references=None) -> np.ndarray:
        planned = self._planned
        if planned is not None and planned[0] == self._version and planned[1] == time and len(planned[2]) == steps:
            return planned[2]
        lengths, rates_half, accels, vib, _ = self._references(time, steps) if references is None else references
        return self.drive.plan(time, lengths[:steps], rates_half[:steps], accels[:steps], vib[:steps])

    def advance(self, duration: float) -> int:
        """Run round(duration / dt) physics steps as one block; returns the number of steps.

        Afterwards ``forces`` holds the axial forces at the new time: those of the step that starts
        there (the next block's controls are planned now and reused if no command arrives). The new state is
        checked (``physics_guard``); a divergence latches ``fault`` (see ``latch_fault``). With a fault latched
        the robot is held and only time goes on.
        """
        steps = max(int(round(duration / self.dt)), 1)
        if self.fault is not None:
            self.sim.data.time = self.time + steps * self.dt
            return steps
        start = self.time
        try:
            self.drive.run(self._controls(start, steps))
            now = self.time
            references = self._references(now, steps)  # the next block's; its first row: the commanded lengths now
            reason = self.guard.check(self._true_strut_reference(references))
            if reason is None and self.plant is not None:
                self._check_unit_travel(now)
            if reason is None:
                self._apply_tissue()  # the tissue's wrench over the next block, from the state now
                controls = self._controls(now, steps, references)
                forces = self.drive.first_force(controls)
                if not np.isfinite(forces).all():
                    reason = "non-finite strut forces planned"
        except (mujoco.FatalError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            reason = f"{type(exc).__name__}: {exc}"
        if reason is not None:
            self.sim.data.time = start + steps * self.dt
            self.latch_fault(reason)
            return steps
        self._planned = (self._version, now, controls)
        self.forces = forces
        return steps

    def _check_unit_travel(self, now: float) -> None:
        """The units' own travel protection (``unit_travel``): a unit sensor beyond the travel ramps the
        vibration out from ``now`` (s); the next block's references then carry the ramp."""
        assert isinstance(self.drive, PlantDrive)
        trip = self.travel.check(self.drive.readings()[1])
        if trip is not None:
            self.safety.stop_vibration(now, trip)

    def _true_strut_reference(self, references) -> np.ndarray:
        """What the MuJoCo slides should be now (6,) m: the commanded hinge lengths (ideal: the slides are
        strut + unit), or the commanded struts in the true frame (the plant: the slides are the struts)."""
        if self.plant is None:
            return references[0][0]
        return references[0][0] - references[3][0] + self.plant.strut_zero_offsets

    # -- read-back ---------------------------------------------------------------
    def joint_state(self):
        """(names, positions, velocities, efforts) for leg_1..6, vib_1..6 at the current time (after a physics
        fault: the held lengths at rest, the vibration units at zero, the last good forces)."""
        if self.plant is not None and self.fault is None:
            assert isinstance(self.drive, PlantDrive)
            return sensed_joint_state(self.drive, self.plant.sensors, self.forces)
        total, rate = self.drive.lengths(), self.drive.rates()
        if self.fault is not None:
            zeros = np.zeros(6)
            return LEG_NAMES + VIB_NAMES, np.concatenate([total, zeros]), np.zeros(12), np.concatenate(
                [self.forces, self.forces])
        _, _, _, vib, vib_rate = self._references(self.time, 0)
        vib, vib_rate = vib[0], vib_rate[0]
        positions = np.concatenate([total - vib, vib])
        velocities = np.concatenate([rate - vib_rate, vib_rate])
        efforts = np.concatenate([self.forces, self.forces])
        return LEG_NAMES + VIB_NAMES, positions, velocities, efforts

    def true_joint_state(self, sensed=None):
        """The ground truth of ``joint_state`` (names, positions, velocities, efforts): leg_* the struts' true
        lengths (m, the plant's frame, no encoder offset) and rates, vib_* the units' true displacements and
        rates, efforts the true axial strut forces (N). Without a plant (or after a fault) the sensors are the
        truth: ``sensed`` (``joint_state``'s answer now, if the caller has it) or ``joint_state``."""
        if self.plant is None or self.fault is not None:
            return self.joint_state() if sensed is None else sensed
        assert isinstance(self.drive, PlantDrive)
        return true_joint_state(self.drive, self.forces)

    def imu_sample(self, quaternion=None) -> ImuSample:
        """The platform IMU's sample now (platform frame, at its origin; see platform_sensors). The
        accelerometer reports the mean specific force since its last sample (integrate and dump: the change of
        the origin's velocity over the interval; qacc is not used, the drives probe the model with it); the
        gyroscope the rate now. ``quaternion``: the platform's orientation now, if the caller has read it."""
        sim, fd = self.sim, self.sim.free_dof
        if quaternion is None:
            _, quaternion = sim.platform_position_quaternion()
        rotation = rotation_from_quaternion(quaternion)
        velocity, now = sim.data.qvel[fd:fd + 3].copy(), self.time
        last = self._imu_velocity
        acceleration = (velocity - last[1]) / (now - last[0]) if last is not None and now > last[0] else np.zeros(3)
        self._imu_velocity = (now, velocity)
        force = specific_force(rotation, acceleration, sim.model.opt.gravity)
        return self.imu.read(force, sim.data.qvel[fd + 3:fd + 6])

    def tracker_frames(self, position=None, quaternion=None) -> list[TrackerFrame]:
        """The optical tracker's frames delivered by now, from the true platform pose now (``position`` (3,) m,
        ``quaternion`` (4,) [x, y, z, w], if the caller has read them)."""
        if position is None or quaternion is None:
            position, quaternion = self.sim.platform_position_quaternion()
        return self.tracker.step(self.time, position, quaternion)

    def platform_pose(self) -> np.ndarray:
        """The platform's ground-truth pose (6,) [x, y, z, roll, pitch, yaw] (m, rad) in the base frame."""
        return self.sim.platform_pose()
