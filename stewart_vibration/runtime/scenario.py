"""Scenario files (config/scenario_*.yaml) for the suite bring-up: load and validate.

A scenario is a list of steps, each ``move_to: paper | home | [x, y, z, roll,
pitch, yaw]`` (m, rad), ``guarded_move_to: <pose>`` (a move the kinematics node's
force guard must stop short of its target) or ``vibrate: {planner parameters}``,
plus the pass/fail bounds of the run summary and optionally ``tissue: <file>``
(a soft-tissue model the emulator applies and kinematics checks against; a relative
path is looked up beside the scenario, then in config/).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import yaml

from ..dynamics.tissue import load_tissue
from ..errors import ConfigError
from ..install import default_config_dir
from ..paper import paper_pose
from ..robot import Robot
from ..vibration.settings import VIBRATION_KEYS, default_settings, duration_reason

VIBRATE_KEYS = set(VIBRATION_KEYS)  # a vibrate step sets these planner settings; the planner's values run for the rest
DEFAULT_BOUNDS = {
    "pose_error_m": 1e-5,
    "pose_error_deg": 0.01,
    "direction_error_deg": 0.5,
    "amplitude_error": 0.02,
    "leg_phase_error_deg": 0.5,
    "leg_frequency_spread_hz": 0.01,
    "leg_frequency_error_hz": 0.01,  # worst leg: measured vs planned frequency
    "force_rms_relative": 0.01,
    "off_axis_ratio": 0.01,  # RMS motion across the planned line / amplitude
    "leg_amplitude_error": 0.02,  # worst leg: measured vs |k_i| A
    "active_duration_error_s": 0.06,  # measured vs planned time at >= half amplitude (two 35 Hz periods)
    "sample_ratio_min": 0.99,  # pose / force / wrench estimates per joint state over the run
    "stream_lag_p99_ms": 500.0,  # per node: p99 of its processing lag (the 500-deep queues hold 1 s at 500 Hz)
    # with a tissue model (issue 17): external-wrench estimate vs the wrench the emulator applied
    "wrench_error_relative": 0.02,  # RMS error in moves and holds / peak applied (force and moment)
    "wrench_error_vibration_n": 1.0,  # RMS force error during a vibration, N
    "guard_overshoot": 0.10,  # after a guard stop: peak estimated force / guard_force_n - 1
}


@dataclass(frozen=True)
class MoveStep:
    """A move_to / guarded_move_to step: ``name`` (home, paper, pose or guarded) and the target ``pose`` (6,)
    [x, y, z, roll, pitch, yaw] (m, rad), platform in the base frame."""

    name: str
    pose: np.ndarray
    guarded: bool = False  # the force guard must stop this move (guarded_move_to)


@dataclass(frozen=True)
class VibrateStep:
    """Planner settings to set before a start (a subset of ``vibration.settings.VIBRATION_KEYS``; duration_s
    always). What ran is what the planner reports in its start answer, which the summary judges against."""

    parameters: dict


@dataclass(frozen=True)
class Scenario:
    """A parsed scenario: its steps (MoveStep, VibrateStep) in order, the run summary's pass/fail ``bounds``
    (DEFAULT_BOUNDS updated by the file), the file it came from and the tissue YAML, if any."""

    name: str
    steps: list
    bounds: dict = field(default_factory=lambda: dict(DEFAULT_BOUNDS))
    source: str = ""
    tissue: str | None = None  # soft-tissue YAML (resolved path) or None


def default_scenario_path() -> Path:
    """scenario_paper.yaml in the config directory (``install.default_config_dir``; ConfigError if none)."""
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
    steps: list[MoveStep | VibrateStep] = []
    for index, step in enumerate(tree["steps"]):
        if not isinstance(step, dict) or len(step) != 1:
            raise ConfigError(f"scenario {path}: step {index} must be one of move_to / guarded_move_to / vibrate")
        (kind, value), = step.items()
        if kind in ("move_to", "guarded_move_to"):
            move = _move(robot, value, path, index)
            steps.append(replace(move, name="guarded", guarded=True) if kind == "guarded_move_to" else move)
        elif kind == "vibrate":
            params = dict(value or {})
            unknown = set(params) - VIBRATE_KEYS
            if unknown:
                raise ConfigError(f"scenario {path}: step {index} unknown vibrate keys {sorted(unknown)}")
            if vibration_duration is not None:
                params["duration_s"] = float(vibration_duration)
            reason = _duration_reason(params, robot)
            if reason:
                raise ConfigError(f"scenario {path}: step {index} {reason}")
            steps.append(VibrateStep(params))
        else:
            raise ConfigError(f"scenario {path}: step {index} has unknown kind '{kind}'")
    bounds = dict(DEFAULT_BOUNDS)
    bounds.update({k: float(v) for k, v in (tree.get("bounds") or {}).items()})
    tissue = resolve_tissue_path(tree["tissue"], path.parent) if tree.get("tissue") else None
    if tissue is not None:
        load_tissue(tissue, robot)  # a bad tissue file fails here, with its reason, before anything starts
    return Scenario(name=str(tree.get("name", path.stem)), steps=steps, bounds=bounds, source=str(path),
                    tissue=tissue)


def _duration_reason(params: dict, robot: Robot) -> str | None:
    """A scenario's vibration must end by itself (duration_s > 0) and follow the planner's rule for a
    duration against its ramps (the planner's default ramp_s where the step sets none)."""
    try:
        duration = float(params.get("duration_s", 0.0))
        ramp = float(params.get("ramp_s", default_settings(robot)["ramp_s"]))
    except (TypeError, ValueError):
        return "duration_s and ramp_s must be numbers"
    if not duration > 0:
        return f"duration_s must be > 0 (a scenario's vibration must end), got {duration}"
    return duration_reason(duration, ramp)


def resolve_tissue_path(value, base: Path) -> str:
    """A tissue file named by a scenario or --tissue: as given, beside the scenario (``base``), or in config/."""
    given = Path(str(value)).expanduser()
    for candidate in (given, base / given, default_config_dir() / given):
        if candidate.is_file():
            return str(candidate.resolve())
    raise ConfigError(f"tissue file {value!r} not found (as given, in {base} or in {default_config_dir()})")


def _move(robot: Robot, value, path, index) -> MoveStep:
    if value == "home":
        return MoveStep("home", robot.home_pose.copy())
    if value == "paper":
        return MoveStep("paper", paper_pose(robot))
    pose = np.asarray(value, dtype=float) if isinstance(value, list) else None
    if pose is None or pose.shape != (6,) or not np.isfinite(pose).all():
        raise ConfigError(f"scenario {path}: step {index} move_to needs paper, home or 6 numbers")
    return MoveStep("pose", pose)
