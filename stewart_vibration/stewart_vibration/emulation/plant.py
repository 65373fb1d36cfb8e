"""The emulated robot's truth: a plant description separate from the controller's model (pure numpy).

The controller plans with config/robot.yaml (the drawing). The plant is the robot as built: its hinges a
few tenths of a millimetre off, its struts' zeros offset, a payload other than nominal, vibration units
with their own resonant dynamics, strut servos with a finite bandwidth and friction, and sensors with
noise. A plant file (config/plant_ideal.yaml, config/plant_realistic.yaml) states these as deviations
from robot.yaml: bounds from which the errors are drawn reproducibly from ``seed``, plus explicit
overrides that win over the drawn values. Only the emulator, the run summary and tests read it; no
controller node may.

Each vibration unit is a resonant voice-coil stage with its own drive (emulation/vibration_unit.py
gives the physical model, why it is plausible, and its documented fixed-base response); the plant file
sets its resonance and damping on its rated load, their spread from unit to unit, the amplifier's
bandwidth and delay.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..config_values import Plausible, as_choice, as_number, as_vector, check_keys
from ..errors import ConfigError
from ..install import config_path, default_config_dir
from ..robot import RigidBody, Robot
from ..safe_yaml import load_yaml

PLANT_KINDS = ("ideal", "realistic")

# Plausible ranges of the plant file's values: wide enough for any fixator-sized robot, narrow enough that a
# unit slip (mm for m, Hz for rad/s) is refused.
HINGE_ERROR = Plausible(0.0, 0.005, "m")
STRUT_OFFSET = Plausible(0.0, 0.005, "m")
SPREAD = Plausible(0.0, 0.5)
COM_ERROR = Plausible(0.0, 0.05, "m")
RESONANCE = Plausible(5.0, 1000.0, "Hz")
DAMPING = Plausible(0.01, 2.0)
GAIN = Plausible(0.5, 2.0)
DRIVER_BANDWIDTH = Plausible(50.0, 100000.0, "Hz")
DELAY = Plausible(0.0, 0.02, "s")
RATED_LOAD = Plausible(0.0, 50.0, "kg")
REFLECTED_MASS = Plausible(0.0, 1000.0, "kg")
SERVO_BANDWIDTH = Plausible(1.0, 500.0, "Hz")
FRICTION_FORCE = Plausible(0.0, 100.0, "N")
VISCOUS_FRICTION = Plausible(0.0, 10000.0, "N s/m")
QUANTIZATION = Plausible(0.0, 1e-4, "m")
DISPLACEMENT_NOISE = Plausible(0.0, 1e-5, "m")
FORCE_NOISE = Plausible(0.0, 10.0, "N")
ACCEL_NOISE_DENSITY = Plausible(0.0, 0.01, "m/s^2/sqrt(Hz)")
GYRO_NOISE_DENSITY = Plausible(0.0, 0.01, "rad/s/sqrt(Hz)")
ACCEL_BIAS = Plausible(0.0, 1.0, "m/s^2")
GYRO_BIAS = Plausible(0.0, 0.1, "rad/s")
TRACKER_RATE = Plausible(1.0, 1000.0, "Hz")
TRACKER_POSITION_NOISE = Plausible(0.0, 0.001, "m")
TRACKER_ORIENTATION_NOISE = Plausible(0.0, 1.0, "deg")
TRACKER_LATENCY = Plausible(0.0, 0.5, "s")
SEED = Plausible(0, 2**32 - 1)

SECTIONS = ("plant", "seed", "geometry", "vibration_units", "struts", "sensors", "overrides")
GEOMETRY_KEYS = ("hinge_error_max_m", "strut_zero_offset_max_m", "payload_mass_spread", "payload_com_error_max_m")
UNIT_KEYS = ("model", "resonance_hz", "damping_ratio", "spread", "driver_bandwidth_hz", "delay_s",
             "suspension_damping_ratio", "rated_load_kg")
STRUT_KEYS = ("model", "bandwidth_hz", "coulomb_friction_n", "viscous_friction_n_s_m", "reflected_mass_kg")
SENSOR_KEYS = ("encoder_quantization_m", "unit_sensor_noise_m", "load_cell_noise_n", "load_cell_offset_max_n",
               "imu", "tracker")
IMU_KEYS = ("accel_noise_density_m_s2_rthz", "gyro_noise_density_rad_s_rthz", "accel_bias_max_m_s2",
            "gyro_bias_max_rad_s")
TRACKER_KEYS = ("rate_hz", "position_noise_m", "orientation_noise_deg", "latency_s")
OVERRIDE_KEYS = ("base_hinge_errors_m", "platform_hinge_errors_m", "strut_zero_offsets_m", "unit_resonance_hz",
                 "unit_gain", "payload_mass_kg", "payload_com_error_m")


@dataclass(frozen=True)
class UnitDynamics:
    """Each vibration unit's dynamics (arrays (6,), legs 1..6).

    model "ideal": the unit is its demand (a displacement source); "resonant": a voice-coil stage
    (emulation/vibration_unit.py) whose resonance on its rated load is ``resonance_hz`` and whose coil's
    force constant is ``gain`` times nominal, its drive tuned for ``nominal_resonance_hz`` and
    ``damping_ratio``, with ``suspension_damping_ratio`` of it passive; ``rated_load_kg``: the load the
    drive is tuned for (besides the slider).
    """

    model: str
    resonance_hz: np.ndarray
    damping_ratio: float
    gain: np.ndarray
    driver_bandwidth_hz: float
    delay_s: float
    nominal_resonance_hz: float = 60.0
    suspension_damping_ratio: float = 0.05
    rated_load_kg: float = 0.0


@dataclass(frozen=True)
class StrutServos:
    """The strut drives: model "ideal" (today's computed-force servo) or "servo" (a position loop of
    ``bandwidth_hz`` on the encoder), with Coulomb (N) and viscous (N s/m) friction per strut (6,) and the
    motor's rotor inertia reflected through the leadscrew onto the strut's axis (kg)."""

    model: str
    bandwidth_hz: float
    coulomb_friction_n: np.ndarray
    viscous_friction_n_s_m: np.ndarray
    reflected_mass_kg: float = 0.0


@dataclass(frozen=True)
class Sensors:
    """What the emulator's sensors add to the truth (SI units; biases and offsets drawn from the seed)."""

    encoder_quantization_m: float
    unit_sensor_noise_m: float  # RMS
    load_cell_noise_n: float  # RMS
    load_cell_offsets_n: np.ndarray  # (6,)
    accel_noise_density: float  # m/s^2/sqrt(Hz)
    gyro_noise_density: float  # rad/s/sqrt(Hz)
    accel_bias_m_s2: np.ndarray  # (3,) platform frame
    gyro_bias_rad_s: np.ndarray  # (3,) platform frame
    tracker_rate_hz: float
    tracker_position_noise_m: float  # RMS per axis
    tracker_orientation_noise_deg: float  # RMS per axis
    tracker_latency_s: float


@dataclass(frozen=True)
class Plant:
    """The robot as built: ``robot`` is robot.yaml with the true hinges and payload; ``strut_zero_offsets``
    (6,) m are added to every true strut length an encoder reports (the encoder reads true - offset)."""

    kind: str
    seed: int
    robot: Robot
    nominal: Robot
    strut_zero_offsets: np.ndarray
    units: UnitDynamics
    struts: StrutServos
    sensors: Sensors
    source: str = ""

    @property
    def base_hinge_errors(self) -> np.ndarray:
        """(6, 3) m: true minus drawn base hinges (base frame)."""
        return self.robot.base_hinges - self.nominal.base_hinges

    @property
    def platform_hinge_errors(self) -> np.ndarray:
        """(6, 3) m: true minus drawn platform hinges (platform frame)."""
        return self.robot.platform_hinges - self.nominal.platform_hinges


def _section(tree: dict, key: str, allowed, where: str) -> dict:
    value = tree.get(key, {})
    if not isinstance(value, dict):
        raise ConfigError(f"{where}: '{key}' must be a mapping")
    check_keys(value, allowed, where, key)
    return value


def _number(tree: dict, key: str, prefix: str, where: str, plausible: Plausible, default: float) -> float:
    return as_number(tree.get(key, default), f"{prefix}.{key}", where, plausible)


def plant_from_dict(tree, nominal: Robot, source: str = "<dict>") -> Plant:
    """The plant a parsed plant file describes (see config/plant_realistic.yaml for every key and its
    meaning); absent keys are ideal (no error, no noise). ConfigError naming the key for a bad value."""
    where = f"plant config {source}"
    if not isinstance(tree, dict):
        raise ConfigError(f"{where}: must be a mapping")
    check_keys(tree, SECTIONS, where)
    if nominal.calibrated:
        raise ConfigError(f"{where}: the plant is stated as deviations from the drawing (config/robot.yaml), but "
                          f"the robot given ({nominal.source}) is a calibrated robot file: the emulated robot is "
                          "built from the drawing")
    kind = as_choice(tree.get("plant", "ideal"), "plant", where, PLANT_KINDS)
    seed = int(as_number(tree.get("seed", 0), "seed", where, SEED, integer=True))
    rng = np.random.default_rng(seed)
    geo = _section(tree, "geometry", GEOMETRY_KEYS, where)
    units_tree = _section(tree, "vibration_units", UNIT_KEYS, where)
    struts_tree = _section(tree, "struts", STRUT_KEYS, where)
    sensors_tree = _section(tree, "sensors", SENSOR_KEYS, where)
    imu = _section(sensors_tree, "imu", IMU_KEYS, where)
    tracker = _section(sensors_tree, "tracker", TRACKER_KEYS, where)
    over = _section(tree, "overrides", OVERRIDE_KEYS, where)

    # every draw happens in a fixed order whatever the bounds and overrides, so a seed means one set of errors
    base_draw, platform_draw = rng.uniform(-1.0, 1.0, (6, 3)), rng.uniform(-1.0, 1.0, (6, 3))
    offset_draw, mass_draw, com_draw = rng.uniform(-1.0, 1.0, 6), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0, 3)
    hinge_max = _number(geo, "hinge_error_max_m", "geometry", where, HINGE_ERROR, 0.0)
    offset_max = _number(geo, "strut_zero_offset_max_m", "geometry", where, STRUT_OFFSET, 0.0)
    mass_spread = _number(geo, "payload_mass_spread", "geometry", where, SPREAD, 0.0)
    com_max = _number(geo, "payload_com_error_max_m", "geometry", where, COM_ERROR, 0.0)
    base_err = hinge_max * base_draw
    platform_err = hinge_max * platform_draw
    offsets = offset_max * offset_draw
    if "base_hinge_errors_m" in over:
        base_err = _matrix(over["base_hinge_errors_m"], "overrides.base_hinge_errors_m", where, HINGE_ERROR)
    if "platform_hinge_errors_m" in over:
        platform_err = _matrix(over["platform_hinge_errors_m"], "overrides.platform_hinge_errors_m", where,
                               HINGE_ERROR)
    if "strut_zero_offsets_m" in over:
        offsets = _signed_vector(over["strut_zero_offsets_m"], "overrides.strut_zero_offsets_m", where, 6,
                                 STRUT_OFFSET)
    payload = nominal.payload
    mass = payload.mass * (1.0 + mass_spread * mass_draw)
    com = payload.com + com_max * com_draw
    if "payload_mass_kg" in over:
        mass = as_number(over["payload_mass_kg"], "overrides.payload_mass_kg", where, Plausible(0.0, 100.0, "kg"))
    if "payload_com_error_m" in over:
        com = payload.com + _signed_vector(over["payload_com_error_m"], "overrides.payload_com_error_m", where, 3,
                                           COM_ERROR)
    scale = mass / payload.mass if payload.mass > 0 else 1.0
    true_payload = RigidBody(mass=mass, com=com, inertia=payload.inertia * scale)
    robot = replace(nominal, base_hinges=nominal.base_hinges + base_err,
                    platform_hinges=nominal.platform_hinges + platform_err, payload=true_payload,
                    source=f"{nominal.source} as built ({source})")

    unit_model = as_choice(units_tree.get("model", "ideal"), "vibration_units.model", where, ("ideal", "resonant"))
    spread = _number(units_tree, "spread", "vibration_units", where, SPREAD, 0.0)
    nominal_resonance = _number(units_tree, "resonance_hz", "vibration_units", where, RESONANCE, 60.0)
    resonance = nominal_resonance * (1.0 + spread * rng.uniform(-1.0, 1.0, 6))
    gain = 1.0 + spread * rng.uniform(-1.0, 1.0, 6)
    if "unit_resonance_hz" in over:
        resonance = as_vector(over["unit_resonance_hz"], "overrides.unit_resonance_hz", where, 6, RESONANCE)
    if "unit_gain" in over:
        gain = as_vector(over["unit_gain"], "overrides.unit_gain", where, 6, GAIN)
    damping = _number(units_tree, "damping_ratio", "vibration_units", where, DAMPING, 0.15)
    units = UnitDynamics(
        model=unit_model, resonance_hz=resonance, gain=gain, damping_ratio=damping,
        driver_bandwidth_hz=_number(units_tree, "driver_bandwidth_hz", "vibration_units", where, DRIVER_BANDWIDTH,
                                    1000.0),
        delay_s=_number(units_tree, "delay_s", "vibration_units", where, DELAY, 0.0),
        nominal_resonance_hz=nominal_resonance,
        suspension_damping_ratio=_number(units_tree, "suspension_damping_ratio", "vibration_units", where,
                                         Plausible(0.0, damping), min(0.05, damping)),
        # the share of the moving body one unit carries (robot.yaml's platform and payload, over six legs)
        rated_load_kg=_number(units_tree, "rated_load_kg", "vibration_units", where, RATED_LOAD,
                              nominal.moving_body.mass / 6))
    struts = StrutServos(
        model=as_choice(struts_tree.get("model", "ideal"), "struts.model", where, ("ideal", "servo")),
        bandwidth_hz=_number(struts_tree, "bandwidth_hz", "struts", where, SERVO_BANDWIDTH, 30.0),
        coulomb_friction_n=np.full(6, _number(struts_tree, "coulomb_friction_n", "struts", where, FRICTION_FORCE,
                                              0.0)),
        viscous_friction_n_s_m=np.full(6, _number(struts_tree, "viscous_friction_n_s_m", "struts", where,
                                                  VISCOUS_FRICTION, 0.0)),
        reflected_mass_kg=_number(struts_tree, "reflected_mass_kg", "struts", where, REFLECTED_MASS, 0.0))
    cell_offset = _number(sensors_tree, "load_cell_offset_max_n", "sensors", where, FORCE_NOISE, 0.0)
    accel_bias = _number(imu, "accel_bias_max_m_s2", "sensors.imu", where, ACCEL_BIAS, 0.0)
    gyro_bias = _number(imu, "gyro_bias_max_rad_s", "sensors.imu", where, GYRO_BIAS, 0.0)
    sensor_draw = rng.uniform(-1.0, 1.0, 12)
    sensors = Sensors(
        encoder_quantization_m=_number(sensors_tree, "encoder_quantization_m", "sensors", where, QUANTIZATION, 0.0),
        unit_sensor_noise_m=_number(sensors_tree, "unit_sensor_noise_m", "sensors", where, DISPLACEMENT_NOISE, 0.0),
        load_cell_noise_n=_number(sensors_tree, "load_cell_noise_n", "sensors", where, FORCE_NOISE, 0.0),
        load_cell_offsets_n=cell_offset * sensor_draw[0:6],
        accel_noise_density=_number(imu, "accel_noise_density_m_s2_rthz", "sensors.imu", where,
                                    ACCEL_NOISE_DENSITY, 0.0),
        gyro_noise_density=_number(imu, "gyro_noise_density_rad_s_rthz", "sensors.imu", where,
                                   GYRO_NOISE_DENSITY, 0.0),
        accel_bias_m_s2=accel_bias * sensor_draw[6:9],
        gyro_bias_rad_s=gyro_bias * sensor_draw[9:12],
        tracker_rate_hz=_number(tracker, "rate_hz", "sensors.tracker", where, TRACKER_RATE, 60.0),
        tracker_position_noise_m=_number(tracker, "position_noise_m", "sensors.tracker", where,
                                         TRACKER_POSITION_NOISE, 0.0),
        tracker_orientation_noise_deg=_number(tracker, "orientation_noise_deg", "sensors.tracker", where,
                                              TRACKER_ORIENTATION_NOISE, 0.0),
        tracker_latency_s=_number(tracker, "latency_s", "sensors.tracker", where, TRACKER_LATENCY, 0.0))
    return Plant(kind=kind, seed=seed, robot=robot, nominal=nominal, strut_zero_offsets=offsets, units=units,
                 struts=struts, sensors=sensors, source=source)


def _signed_vector(value, key: str, where: str, length: int, magnitude: Plausible) -> np.ndarray:
    """A (length,) vector whose entries' magnitudes lie in ``magnitude``."""
    vector = as_vector(value, key, where, length)
    for i, v in enumerate(vector):
        as_number(abs(v), f"{key}[{i}] (magnitude)", where, magnitude)
    return vector


def _matrix(value, key: str, where: str, magnitude: Plausible) -> np.ndarray:
    """A (6, 3) list of lists whose entries' magnitudes lie in ``magnitude``."""
    if not isinstance(value, list) or len(value) != 6:
        raise ConfigError(f"{where}: '{key}' must be a list of 6 [x, y, z] lists")
    return np.array([_signed_vector(row, f"{key}[{i}]", where, 3, magnitude) for i, row in enumerate(value)])


def load_plant(path: str | Path, nominal: Robot, seed: int | None = None) -> Plant:
    """The plant of the YAML file ``path`` for the controller's robot ``nominal``; ``seed`` (e.g. from
    --plant-seed) replaces the file's own. ConfigError naming the file and the key for a bad value."""
    tree = load_yaml(path, "plant config")
    if seed is not None:
        tree = dict(tree, seed=seed)
    return plant_from_dict(tree, nominal, str(path))


def load_plant_option(value: str | None, nominal: Robot, seed: int | None = None) -> Plant | None:
    """The emulator's ``plant_config`` parameter (or the main job's --plant): '' or None = the drawing
    (no plant); "ideal" or "realistic" = config/plant_<name>.yaml; else a YAML path (a relative path that is
    not a file is tried in the config directory). ``seed`` (>= 0) replaces the file's. ConfigError as
    ``load_plant``."""
    if not value:
        return None
    path = default_config_dir() / f"plant_{value}.yaml" if value in PLANT_KINDS else config_path(value)
    return load_plant(path, nominal, seed)
