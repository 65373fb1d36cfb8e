"""Scenario files (config/scenario_*.yaml) for the suite bring-up: load and validate.

A scenario is a list of steps, each ``move_to: paper | home | [x, y, z, roll,
pitch, yaw]`` (m, rad) or ``vibrate: {planner parameters}``, plus the pass/fail
bounds of the run summary.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from .errors import ConfigError
from .paper import paper_pose
from .robot import Robot, default_config_dir

VIBRATE_KEYS = {"direction", "frame", "amplitude_m", "acceleration_g", "frequency_hz", "phase_rad", "duration_s",
                "ramp_s"}
DEFAULT_BOUNDS = {
    "pose_error_m": 1e-5,
    "pose_error_deg": 0.01,
    "direction_error_deg": 0.5,
    "amplitude_error": 0.02,
    "leg_phase_error_deg": 0.5,
    "leg_frequency_spread_hz": 0.01,
    "force_rms_relative": 0.01,
    "off_axis_ratio": 0.01,  # RMS motion across the planned line / amplitude
    "leg_amplitude_error": 0.02,  # worst leg: measured vs |k_i| A
    "active_duration_error_s": 0.06,  # measured vs planned time at >= half amplitude (two 35 Hz periods)
    "sample_ratio_min": 0.99,  # pose / force / wrench estimates per joint state over the run
}


@dataclass(frozen=True)
class MoveStep:
    name: str
    pose: np.ndarray


@dataclass(frozen=True)
class VibrateStep:
    parameters: dict

    @property
    def duration(self) -> float:
        return float(self.parameters["duration_s"])

    @property
    def ramp(self) -> float:
        return float(self.parameters.get("ramp_s", 0.2))

    @property
    def frequency(self) -> float:
        return float(self.parameters.get("frequency_hz", 35.0))


@dataclass(frozen=True)
class Scenario:
    name: str
    steps: list
    bounds: dict = field(default_factory=lambda: dict(DEFAULT_BOUNDS))
    source: str = ""


def default_scenario_path() -> Path:
    return default_config_dir() / "scenario_paper.yaml"


def load_scenario(robot: Robot, path=None, vibration_duration: float | None = None) -> Scenario:
    """Parse a scenario file; ``vibration_duration`` (s) overrides every vibrate step's duration_s."""
    path = Path(path) if path else default_scenario_path()
    try:
        tree = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ConfigError(f"cannot read scenario {path}: {exc}") from None
    if not isinstance(tree, dict) or not isinstance(tree.get("steps"), list) or not tree["steps"]:
        raise ConfigError(f"scenario {path}: needs a non-empty 'steps' list")
    steps = []
    for index, step in enumerate(tree["steps"]):
        if not isinstance(step, dict) or len(step) != 1:
            raise ConfigError(f"scenario {path}: step {index} must be one of move_to / vibrate")
        (kind, value), = step.items()
        if kind == "move_to":
            steps.append(_move(robot, value, path, index))
        elif kind == "vibrate":
            params = dict(value or {})
            unknown = set(params) - VIBRATE_KEYS
            if unknown:
                raise ConfigError(f"scenario {path}: step {index} unknown vibrate keys {sorted(unknown)}")
            if vibration_duration is not None:
                params["duration_s"] = float(vibration_duration)
            if float(params.get("duration_s", 0)) <= 2 * float(params.get("ramp_s", 0.2)):
                raise ConfigError(f"scenario {path}: step {index} duration_s must exceed two ramps")
            steps.append(VibrateStep(params))
        else:
            raise ConfigError(f"scenario {path}: step {index} has unknown kind '{kind}'")
    bounds = dict(DEFAULT_BOUNDS)
    bounds.update({k: float(v) for k, v in (tree.get("bounds") or {}).items()})
    return Scenario(name=str(tree.get("name", path.stem)), steps=steps, bounds=bounds, source=str(path))


def _move(robot: Robot, value, path, index) -> MoveStep:
    if value == "home":
        return MoveStep("home", robot.home_pose.copy())
    if value == "paper":
        return MoveStep("paper", paper_pose(robot))
    pose = np.asarray(value, dtype=float) if isinstance(value, list) else None
    if pose is None or pose.shape != (6,) or not np.isfinite(pose).all():
        raise ConfigError(f"scenario {path}: step {index} move_to needs paper, home or 6 numbers")
    return MoveStep("pose", pose)
