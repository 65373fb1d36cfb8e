"""The realistic plant's drives, stepped once per physics step (no rclpy): strut servos that see only their
encoders, and each vibration unit's own firmware and amplifier (``vibration_unit``).

Strut servo (per leg, a position loop of ``bandwidth_hz`` on the encoder, no feedforward from any model):

    F = kp (L_ref - L_enc) + kv (L_ref_rate - L_enc_rate) + ki dt sum (L_ref - L_enc)

with L_enc the encoder's reading (the true strut length minus the plant's zero offset, quantized) and its
rate the reading's difference over one step; kp = m w^2, kv = 2 zeta m w, ki = kp w / 20 with m the leg's
effective mass at the start pose with rigid legs (the servo's own tuning on the robot as built). The
leadscrew's reflected rotor inertia is MuJoCo's armature on the strut slide (it makes the strut a heavy,
stiff position actuator); the struts' Coulomb and viscous friction are MuJoCo's ``frictionloss`` and joint
damping there. The references are the controller's: strut lengths and unit displacement demands in the
controller's (nominal) frame.

Vibration units: each step the unit's sensor reads the slider's displacement (plus the plant's sensor
noise); the coil force of ``UnitLoop`` plus the flexure's damping (explicit) drives actuator ``vib_i``.

Every force is computed from the state at the step's start (the sensors sample, then the step runs): one
numpy pass of a few vector operations a step.
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..robot import LEG_NAMES, VIB_NAMES
from ..sim.mujoco_sim import StewartSim
from .plant import Plant
from .vibration_unit import UnitHardware, UnitLoop

# The strut servo's integral corner as a fraction of its bandwidth. The servos are tuned per leg, but the platform
# also rocks on all six at 9-10 Hz, a mode they barely damp; with a fifth of the bandwidth, a payload 30 % heavier
# while the units vibrate (their dither takes the struts' friction away) makes that mode grow. A twentieth keeps
# it decaying and still removes a static error within ~0.1 s.
INTEGRAL_RATIO = 0.05


def acceleration_sensitivity(model, data, dofs, actuators) -> tuple[np.ndarray, np.ndarray]:
    """(qacc[dofs] with every actuator at zero force, d qacc[dofs] / d ctrl[actuators]) at the state in ``data``
    (mj_forward, then one partial forward per actuator: the accelerations are affine in the forces); ctrl is
    left at zero."""
    data.ctrl[:] = 0.0
    mujoco.mj_forward(model, data)
    base = data.qacc[dofs].copy()
    gain = np.empty((len(dofs), len(actuators)))
    for k, actuator in enumerate(actuators):
        data.ctrl[:] = 0.0
        data.ctrl[actuator] = 1.0
        mujoco.mj_forwardSkip(model, data, mujoco.mjtStage.mjSTAGE_VEL, 1)
        gain[:, k] = data.qacc[dofs] - base
    data.ctrl[:] = 0.0
    return base, gain


def effective_strut_masses(sim: StewartSim) -> np.ndarray:
    """Each strut's effective mass (6,) kg at the sim's state: 1 / (d L_ddot / d F)_ii (call it on a model
    without friction: at rest its constraint takes a small force whole)."""
    _, gain = acceleration_sensitivity(sim.model, sim.data, sim.slide_dof, range(6))
    mujoco.mj_forward(sim.model, sim.data)
    return 1.0 / np.diag(gain)


class PlantDrive:
    """Strut servos on the encoders and the vibration units' drives of a StewartSim built with unit sliders.

    ``rigid``: the same robot without unit sliders at the same state, on which the servos are tuned (the
    mass a strut moves at its bandwidth is the platform's share through the stiff unit, not the piston's
    alone); default ``sim``."""

    def __init__(self, sim: StewartSim, plant: Plant, units: UnitHardware, bandwidth_hz: float,
                 damping_ratio: float = 1.0, seed: int = 0, rigid: StewartSim | None = None):
        self.sim, self.plant, self.units = sim, plant, units
        self.model, self.data = sim.model, sim.data
        m, d = self.model, self.data
        self.slide_q, self.slide_v = sim.slide_qpos, sim.slide_dof
        vib = [m.joint(name).id for name in VIB_NAMES]
        self.vib_q = np.array([m.jnt_qposadr[j] for j in vib])
        self.vib_v = np.array([m.jnt_dofadr[j] for j in vib])
        # mjcf builds the struts' actuators first, then the units': two contiguous blocks of ctrl
        assert [m.actuator(name).id for name in LEG_NAMES + VIB_NAMES] == list(range(12))
        struts = plant.struts
        for each in (sim,) if rigid is None else (sim, rigid):
            each.model.dof_armature[each.slide_dof] = struts.reflected_mass_kg
        mass = effective_strut_masses(rigid if rigid is not None else sim)
        m.dof_frictionloss[self.slide_v] = struts.coulomb_friction_n
        m.dof_damping[self.slide_v] = struts.viscous_friction_n_s_m
        omega = 2.0 * np.pi * bandwidth_hz
        self.kp, self.kv = mass * omega**2, 2.0 * damping_ratio * mass * omega
        self.ki = self.kp * INTEGRAL_RATIO * omega
        self.offsets = plant.strut_zero_offsets
        sensors = plant.sensors
        self.quantum = sensors.encoder_quantization_m
        self.unit_noise = sensors.unit_sensor_noise_m
        self.rng = np.random.default_rng(seed)
        self.loop = UnitLoop(units)
        self.dt = float(m.opt.timestep)
        self.strut_forces = np.zeros(6)
        self.unit_forces = np.zeros(6)
        self.transmitted_forces = np.zeros(6)  # through the struts at the state now (``first_force``)
        self._probe = mujoco.MjData(m)  # a scratch state for that forward pass
        self._integral = np.zeros(6)
        self._previous_encoder = self.encoders()
        self._previous_reference = self._previous_encoder.copy()
        self._unit_reading = np.zeros(6)
        self._previous_unit_reading = np.zeros(6)
        d.ctrl[:] = 0.0

    # -- sensors -----------------------------------------------------------------------
    def encoders(self) -> np.ndarray:
        """The strut encoders' readings (6,) m: true strut length minus the zero offset, quantized."""
        reading = self.data.qpos[self.slide_q] - self.offsets
        if self.quantum > 0:
            reading = np.round(reading / self.quantum) * self.quantum
        return reading

    def readings(self) -> tuple[np.ndarray, np.ndarray]:
        """(encoders, unit sensors) (6,) each, m: what the sensors read now (the unit sensors: the reading
        the firmware used at the last step)."""
        return self.encoders(), self._unit_reading.copy()

    def reading_rates(self) -> tuple[np.ndarray, np.ndarray]:
        """(encoder rates, unit sensor rates) (6,) each, m/s: the readings' change over the last step."""
        return ((self.encoders() - self._previous_encoder) / self.dt,
                (self._unit_reading - self._previous_unit_reading) / self.dt)

    def unit_displacements(self) -> np.ndarray:
        """The units' true displacements (6,) m."""
        return self.data.qpos[self.vib_q].copy()

    def lengths(self) -> np.ndarray:
        """The hinge-to-hinge leg lengths (6,) m the sensors see now (encoder + unit sensor, the controller's
        frame)."""
        strut, unit = self.readings()
        return strut + unit

    def rates(self) -> np.ndarray:
        """The sensed hinge-to-hinge leg length rates (6,) m/s (``reading_rates`` summed)."""
        strut, unit = self.reading_rates()
        return strut + unit

    # -- state -------------------------------------------------------------------------
    def static_forces(self) -> tuple[np.ndarray, np.ndarray]:
        """(strut forces, coil forces) (6,) N each that hold the state now at rest: MuJoCo's accelerations of
        the twelve slides are affine in the twelve actuator forces; solved for zero (friction off meanwhile:
        its constraint would take a small force whole)."""
        m, d = self.model, self.data
        dofs = np.concatenate([self.slide_v, self.vib_v])
        friction = m.dof_frictionloss[self.slide_v].copy()
        m.dof_frictionloss[self.slide_v] = 0.0
        velocity = d.qvel.copy()
        d.qvel[:] = 0.0
        base, gain = acceleration_sensitivity(m, d, dofs, range(12))  # struts, then units (see __init__)
        forces = np.linalg.solve(gain, -base)
        m.dof_frictionloss[self.slide_v] = friction
        d.qvel[:] = velocity
        d.ctrl[:] = forces
        mujoco.mj_forward(m, d)
        return forces[:6], forces[6:]

    def restart(self) -> None:
        """Start the loops from the state now (set from outside, at rest), the struts and units delivering
        the forces that hold it (``static_forces``) so nothing jumps."""
        strut, coil = self.static_forces()
        self._previous_encoder = self.encoders()
        self._previous_reference = self._previous_encoder.copy()
        self._integral = strut / (self.ki * self.dt)
        self.strut_forces, self.unit_forces = strut, coil
        self.transmitted_forces = strut.copy()  # at rest, no friction: the rotor takes nothing
        x = self.data.qpos[self.vib_q]
        self._unit_reading = x.copy()
        self._previous_unit_reading = x.copy()
        # the static solve holds the flexure's pull at x too (the joint spring is MuJoCo's)
        self.loop.reset(x, coil)

    def plan(self, time: float, lengths, rates_half_back, accels, vib=None) -> np.ndarray:
        """The block's references [n, 12]: strut lengths (the commanded lengths minus the unit demands,
        controller frame) and unit demands, from the emulator's reference rows (``vib`` [n, 6] m)."""
        vib = np.zeros_like(lengths) if vib is None else np.asarray(vib)
        return np.hstack([np.asarray(lengths) - vib, vib])

    def first_force(self, controls: np.ndarray) -> np.ndarray:
        """The axial forces (6,) N the struts transmit at the state now (what the load cells and the truth
        report): those of the step that starts here, with the servo's force for ``controls``' first row and the
        coil forces the units' amplifiers hold, from a forward pass on a scratch copy of the state. MuJoCo's
        accelerations and constraint forces after a step are those at its start, one step before the state's
        stamp: 6 deg of phase at 35 Hz with 2 kHz physics."""
        m, d, probe = self.model, self.data, self._probe
        probe.time = d.time
        probe.qpos[:], probe.qvel[:], probe.qacc_warmstart[:] = d.qpos, d.qvel, d.qacc_warmstart
        servo = self._servo_force(np.asarray(controls)[0, :6], self.encoders(), self._integral)
        probe.ctrl[:6] = servo
        probe.ctrl[6:12] = self.loop.next_force() - self.units.damping_n_s_m * d.qvel[self.vib_v]
        mujoco.mj_forward(m, probe)
        self.transmitted_forces = self._transmitted(servo, probe)
        return self.transmitted_forces.copy()

    def _servo_force(self, reference: np.ndarray, encoder: np.ndarray, integral: np.ndarray) -> np.ndarray:
        """The strut servos' forces (6,) N for a step towards ``reference`` from ``encoder`` (m), ``integral`` the
        error sum before it (not updated here)."""
        error = reference - encoder
        rate_error = (reference - self._previous_reference) - (encoder - self._previous_encoder)
        return self.kp * error + self.kv * rate_error / self.dt + self.ki * self.dt * (integral + error)

    def _transmitted(self, servo: np.ndarray, d) -> np.ndarray:
        """The axial force (6,) N each strut's piston receives across its slide in the state of MjData ``d`` after
        a forward pass with the servo's force ``servo``: that force, plus the screw's viscous and Coulomb
        friction, less what the reflected rotor mass takes to accelerate. An in-line load cell at the piston
        reads this, not the motor's force: at 35 Hz the rotor's share is about half of it."""
        m = self.model
        n = d.nefc
        friction = np.zeros(m.nv)
        rows = d.efc_type[:n] == mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF
        np.add.at(friction, d.efc_id[:n][rows], d.efc_force[:n][rows])
        v = self.slide_v
        return servo + d.qfrc_passive[v] + friction[v] - m.dof_armature[v] * d.qacc[v]

    def run(self, controls: np.ndarray) -> None:
        """One physics step per row of ``controls`` [n, 12] (strut references, unit demands)."""
        m, d = self.model, self.data
        ctrl, step = d.ctrl, mujoco.mj_step
        loop, c_unit = self.loop, self.units.damping_n_s_m
        noise = self.rng.normal(0.0, self.unit_noise, (len(controls), 6)) if self.unit_noise > 0 else None
        for k, row in enumerate(controls):
            reference, demand = row[:6], row[6:]
            encoder = self.encoders()
            forces = self._servo_force(reference, encoder, self._integral)
            self._integral += reference - encoder
            self._previous_reference, self._previous_encoder = reference, encoder
            x = d.qpos[self.vib_q]
            reading = x if noise is None else x + noise[k]  # x: a copy (fancy indexing)
            self._previous_unit_reading, self._unit_reading = self._unit_reading, reading
            unit = loop.coil_force(demand, reading) - c_unit * d.qvel[self.vib_v]
            ctrl[:6] = forces
            ctrl[6:12] = unit
            self.strut_forces, self.unit_forces = forces, unit
            step(m, d)
