"""Each vibration unit as a physical actuator: a resonant voice-coil stage with its own drive (pure numpy).

The unit sits in series with its strut: the stator is fixed to the strut's piston and the slider, a moving
mass on a flexure suspension, carries the spherical joint to the platform. The suspension's stiffness and
the mass the slider carries set the unit's resonance: it is a spring-mass (resonant) actuator. A voice coil
drives the slider through a current amplifier (first-order bandwidth ``w_d``, ``N`` samples of transport
delay), and the unit's firmware computes the coil command at the physics rate ``1/dt`` from the
displacement demand d and its own displacement sensor's reading y:

    u_n = k0 d_n + Ki dt sum_k<=n (d_k - y_k) - Kd (y_n - y_n-1) / dt
    f_n+1 = a f_n + (1 - a) u_n-N,    a = exp(-w_d dt)     (amplifier: exact first-order lag, delay N)
    coil force = kappa f_n                                 (kappa the unit's force-constant error)

``k0 d`` is the force that holds the nominal spring at the demand (the drive), ``Kd`` adds velocity
damping to the suspension's own, and the integral (corner two decades below the resonance) holds the static
leg force, so the unit's mean position does not sag under the platform's weight. The manufacturer sets
k0 and Kd for the rated load ``M`` (slider plus the share of the platform one unit carries) on a fixed base:
a resonance ``f_n`` and a damping ratio ``zeta`` (``design_hardware``; Kd is raised by 1 / cos of the
loop's lag at the resonance, which the delayed velocity feedback loses). Units differ in their suspension
(the resonance spread) and their coil's force constant kappa (the gain spread). In the closed chain a unit
carries the platform's inertia, the payload and the tissue instead of its rated load, so its response
there differs from the fixed-base one, as a real unit's does; and an uncompensated demand at 35 Hz comes
out with the amplitude and phase of the unit's resonance, not the demanded ones.

Why this is plausible for a fixator-mounted linear vibration unit: low-magnitude high-frequency units
deliver 10-100 um at 20-90 Hz against loads of a few to tens of newtons; a moving-coil actuator on a
flexure guide (a linear resonant actuator) gives that stroke with little power when tuned a little above
the clinical band, and a displacement sensor with slow integral action keeps its mean position under the
static load. The amplifier's delay limits how much the feedback can do, so the drive is mostly
feedforward and the response keeps the suspension's resonance.

``fixed_base_response`` is the exact response of this sampled drive on a slider of mass ``M`` integrated
by semi-implicit Euler (MuJoCo's Euler) at ``dt``: the unit's documented demand-to-displacement response.
It holds for the physics the emulator runs: the flexure's spring is MuJoCo's joint stiffness (explicit in
Euler) and its damping is applied with the coil force from the velocity at the step's start (MuJoCo's
Euler would take joint damping implicitly, another response).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .plant import UnitDynamics

# the integral's corner, a fraction of the resonance: it holds the load without shaping the band, and is slow
# beside the strut servo's integral in series with it (at a tenth of the resonance the two beat and grow)
INTEGRAL_CORNER = 0.01


@dataclass(frozen=True)
class UnitHardware:
    """Six vibration units' physical and drive parameters (SI; arrays (6,), legs 1..6).

    moving_mass_kg: the slider alone; rated_mass_kg: slider plus rated load (what the drive is tuned for);
    stiffness_n_m / damping_n_s_m (6,): each unit's flexure suspension; force_constant_error (6,): kappa;
    drive_stiffness_n_m (k0), ki (N/(m s)), kd (N s/m): the shared firmware gains; driver_pole: a =
    exp(-w_d dt); delay_steps: N; dt: the drive and physics period (s).
    """

    moving_mass_kg: float
    rated_mass_kg: float
    stiffness_n_m: np.ndarray
    damping_n_s_m: np.ndarray
    force_constant_error: np.ndarray
    drive_stiffness_n_m: float
    ki: float
    kd: float
    driver_pole: float
    delay_steps: int
    dt: float


def design_hardware(resonance_hz, gain, damping_ratio: float, nominal_resonance_hz: float,
                    driver_bandwidth_hz: float, delay_s: float, moving_mass_kg: float, rated_load_kg: float,
                    suspension_damping_ratio: float, dt: float) -> UnitHardware:
    """The units' hardware: suspensions giving each unit the resonance ``resonance_hz`` (6,) Hz on its
    rated load (``moving_mass_kg + rated_load_kg``, kg) with the passive ``suspension_damping_ratio``;
    coils with the force-constant errors ``gain`` (6,); the firmware tuned for ``nominal_resonance_hz``
    and ``damping_ratio``. The delay is rounded to whole periods of ``dt`` (s)."""
    mass = moving_mass_kg + rated_load_kg
    w = 2 * np.pi * np.asarray(resonance_hz, float)
    wn = 2 * np.pi * nominal_resonance_hz
    delay_steps = int(round(delay_s / dt))
    # the loop's lag at the resonance, as a delay: transport, amplifier, its one-period discrete step and
    # the velocity difference's half period
    lag = delay_steps * dt + 1.0 / (2 * np.pi * driver_bandwidth_hz) + 1.5 * dt
    added = max(damping_ratio - suspension_damping_ratio, 0.0)
    kd = 2 * added * mass * wn / max(np.cos(wn * lag), 0.2)
    k0 = mass * wn**2
    return UnitHardware(moving_mass_kg=float(moving_mass_kg), rated_mass_kg=float(mass), stiffness_n_m=mass * w**2,
                        damping_n_s_m=2 * suspension_damping_ratio * mass * w,
                        force_constant_error=np.asarray(gain, float).copy(), drive_stiffness_n_m=k0,
                        ki=k0 * INTEGRAL_CORNER * wn, kd=kd,
                        driver_pole=float(np.exp(-2 * np.pi * driver_bandwidth_hz * dt)),
                        delay_steps=delay_steps, dt=float(dt))


def unit_hardware(units: UnitDynamics, moving_mass_kg: float, dt: float) -> UnitHardware:
    """The hardware of the plant's resonant units (``units``), sliders of ``moving_mass_kg`` (kg, robot.yaml's
    vibration unit), drive period ``dt`` (s)."""
    return design_hardware(units.resonance_hz, units.gain, units.damping_ratio, units.nominal_resonance_hz,
                           units.driver_bandwidth_hz, units.delay_s, moving_mass_kg, units.rated_load_kg,
                           units.suspension_damping_ratio, dt)


def fixed_base_response(hw: UnitHardware, frequencies_hz, mass_kg: float | None = None) -> np.ndarray:
    """Complex demand-to-displacement response (6, F) of each unit on a fixed base carrying ``mass_kg``
    (slider and load; default the rated mass), at ``frequencies_hz`` (F,): the exact response of the
    sampled drive with the slider integrated by semi-implicit Euler at ``dt``."""
    m = hw.rated_mass_kg if mass_kg is None else float(mass_kg)
    dt = hw.dt
    z = np.exp(2j * np.pi * np.asarray(frequencies_hz, float) * dt)[None, :]
    k, c = hw.stiffness_n_m[:, None], hw.damping_n_s_m[:, None]
    # slider: v+ = v + dt (F - k x - c v) / m, x+ = x + dt v+  =>  X / F
    plant = 1.0 / ((m * (z - 1) + c * dt) * (z - 1) / (dt**2 * z) + k)
    amplifier = (1 - hw.driver_pole) * z ** (-hw.delay_steps) / (z - hw.driver_pole)
    integral = hw.ki * dt * z / (z - 1)
    derivative = hw.kd * (z - 1) / (z * dt)
    forward = plant * hw.force_constant_error[:, None] * amplifier
    return forward * (hw.drive_stiffness_n_m + integral) / (1 + forward * (integral + derivative))


class UnitLoop:
    """The six units' firmware and amplifiers, one physics period at a time (vectorised over the units).

    ``coil_force(demand, displacement)`` is called once per period with the demand d_n (6,) m and the
    slider's displacement x_n (6,) m (the sensor reads x, plus ``noise`` (6,) m if given); it returns the
    coil forces (6,) N to apply during this period.
    """

    def __init__(self, hw: UnitHardware):
        self.hw = hw
        self.reset()

    def reset(self, reading=None, holding_force=None) -> None:
        """Start from rest at sensor ``reading`` (6,) m (default 0) with the amplifier delivering
        ``holding_force`` (6,) N (default 0), held by the integral, so a loaded unit starts without a jump."""
        hw = self.hw
        y = np.zeros(6) if reading is None else np.asarray(reading, float).copy()
        force = np.zeros(6) if holding_force is None else np.asarray(holding_force, float) / hw.force_constant_error
        self._previous_reading = y
        # at rest on the demand y the command is k0 y + Ki dt sum e: the integral holds the rest
        held = force - hw.drive_stiffness_n_m * y
        self._integral = held / (hw.ki * hw.dt) if hw.ki > 0 else np.zeros(6)
        self._amplifier = force.copy()
        self._pending = np.tile(force, (hw.delay_steps, 1))  # commands in the delay line, oldest first
        self._head = 0

    def next_force(self) -> np.ndarray:
        """The coil forces (6,) N the next ``coil_force`` call applies (the amplifiers' output now)."""
        return self.hw.force_constant_error * self._amplifier

    def coil_force(self, demand, displacement, noise=None) -> np.ndarray:
        """Coil forces (6,) N for this period (see the class docstring)."""
        hw = self.hw
        y = np.asarray(displacement, float)
        if noise is not None:
            y = y + noise
        d = np.asarray(demand, float)
        self._integral += d - y
        velocity = (y - self._previous_reading) / hw.dt
        command = hw.drive_stiffness_n_m * d + hw.ki * hw.dt * self._integral - hw.kd * velocity
        self._previous_reading = y
        if hw.delay_steps:
            delayed = self._pending[self._head].copy()
            self._pending[self._head] = command
            self._head = (self._head + 1) % hw.delay_steps
        else:
            delayed = command
        applied = hw.force_constant_error * self._amplifier
        self._amplifier = hw.driver_pole * self._amplifier + (1 - hw.driver_pole) * delayed
        return applied
