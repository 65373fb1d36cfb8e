"""The emulated robot as its node's parameters describe it (pure Python): at configure the robot as drawn, the
simulation at the physics rate, the optional soft tissue and plant, built into a HardwareEmulator, with the
line that says what was built; while it runs the live parameters of its vibration buffer. The names are the
hardware_emulator node's parameter names (``SETUP_PARAMETERS``, ``LIVE_PARAMETERS``)."""

from __future__ import annotations

from dataclasses import dataclass

from ..dynamics.tissue import TissueModel
from ..dynamics.tissue_config import load_tissue_option
from ..kinematics.robot_config import load_drawing
from ..robot import Robot
from ..sim.mjcf import SimulationSettings, load_simulation_settings
from .emulator import HardwareEmulator
from .plant import Plant, load_plant_option

SETUP_PARAMETERS = ("robot_config", "simulation_config", "physics_rate_hz", "tissue_config", "plant_config",
                    "plant_seed", "watchdog_s", "vibration_ramp_s", "drive_gain_interval", "max_lookahead_s",
                    "state_rate_hz")
# parameter -> the VibrationBuffer attribute it sets while the emulator runs (s)
LIVE_PARAMETERS = {"watchdog_s": "watchdog_s", "vibration_ramp_s": "ramp_s", "max_lookahead_s": "max_lookahead_s"}


@dataclass(frozen=True)
class EmulatorSetup:
    """A built emulator and what it was built from."""

    emulator: HardwareEmulator
    robot: Robot
    settings: SimulationSettings
    tissue: TissueModel | None
    plant: Plant | None

    def summary(self) -> str:
        """One line for the log: the physics step and integrator, the robot, tissue and plant files."""
        tissue, plant = self.tissue, self.plant
        built = f"{plant.kind} seed {plant.seed} ({plant.source})" if plant is not None else "ideal"
        return (f"MuJoCo dt {self.emulator.dt} s, {self.settings.emulator_integrator}, robot {self.robot.source}, "
                f"tissue {f'{tissue.name} ({tissue.source})' if tissue is not None else 'none'}, plant {built}")

    def facts(self) -> dict[str, object]:
        """The values /diagnostics shows about the build: servo bandwidth (Hz), tissue file, plant kind and seed."""
        return dict(servo_bandwidth_hz=self.settings.servo_bandwidth_hz,
                    tissue=self.tissue.source if self.tissue is not None else "none",
                    plant=f"{self.plant.kind} (seed {self.plant.seed})" if self.plant is not None else "ideal")


def build_emulator(*, robot_config: str, simulation_config: str, physics_rate_hz: float, tissue_config: str,
                   plant_config: str, plant_seed: int, watchdog_s: float, vibration_ramp_s: float,
                   drive_gain_interval: int, max_lookahead_s: float, state_rate_hz: float,
                   start_time: float) -> EmulatorSetup:
    """The emulator from its files ('' = the packaged default, or none for tissue and plant): the robot as
    drawn (a calibrated file is the controller's model of this robot, not the robot), physics at
    ``physics_rate_hz`` (Hz), a plant seeded with ``plant_seed`` when >= 0 (else the file's seed), the
    vibration buffer's ``watchdog_s``, ``vibration_ramp_s`` and ``max_lookahead_s`` (s), sensors at
    ``state_rate_hz`` (Hz), sim time starting at ``start_time`` (s).

    Raises:
        StewartError, ValueError, OSError: a file that cannot be read or a value it cannot take.
    """
    robot = load_drawing(robot_config or None)
    settings = load_simulation_settings(simulation_config or None, timestep=1.0 / physics_rate_hz)
    tissue = load_tissue_option(tissue_config, robot)
    seed = int(plant_seed)
    plant = load_plant_option(plant_config, robot, seed if seed >= 0 else None)
    emulator = HardwareEmulator(robot, settings, watchdog_s, vibration_ramp_s, drive_gain_interval, max_lookahead_s,
                                tissue=tissue, plant=plant, sensor_rate_hz=state_rate_hz, start_time=start_time)
    return EmulatorSetup(emulator, robot, settings, tissue, plant)


def set_live_parameter(emulator: HardwareEmulator, name: str, value: float) -> None:
    """Parameter ``name`` (a key of LIVE_PARAMETERS) set to ``value`` (s) on a running ``emulator``."""
    setattr(emulator.vibration, LIVE_PARAMETERS[name], float(value))
