"""Scenario files (config/scenario_*.yaml) for the suite bring-up: load and validate.

A scenario is a list of steps, each ``move_to: paper | home | [x, y, z, roll,
pitch, yaw]`` (m, rad), ``guarded_move_to: <pose>`` (a move the kinematics node's
force guard must stop short of its target) or ``vibrate: {vibration settings}`` (the keys of a vibrate goal),
plus the pass/fail bounds of the run summary and optionally ``tissue: <file>``
(a soft-tissue model the emulator applies and kinematics checks against; a relative
path is looked up beside the scenario, then in config/).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..config_values import Plausible, as_choice, as_number, as_vector, check_keys
from ..dynamics.tissue_config import load_tissue
from ..errors import ConfigError, StewartError
from ..install import default_config_dir
from ..kinematics import check_pose
from ..paper import paper_pose
from ..robot import Robot
from ..safe_yaml import load_yaml, short_repr
from ..vibration.decompose import FRAMES
from ..vibration.settings import VIBRATION_KEYS, default_settings, settings_reason

# the fracture site on the tibia axis, platform frame (m): 60 mm from the platform ring toward the base ring,
# where config/tissue.yaml centres the tissue. The moves' reduction accuracy is reported there.
DEFAULT_FRACTURE_SITE_M = (0.0, 0.0, -0.060)
FRACTURE_SITE = Plausible(-1.0, 1.0, "m")
VIBRATE_KEYS = set(VIBRATION_KEYS)  # a vibrate step sets these planner settings; the planner's values run for the rest
DEFAULT_BOUNDS = {
    "pose_error_m": 1e-5,
    "pose_error_deg": 0.01,
    # reduction accuracy at the scenario's fracture site (the distal fragment's residual after each move)
    "fracture_displacement_mm": 0.05,
    "fracture_angulation_deg": 0.01,
    "fracture_rotation_deg": 0.01,
    "direction_error_deg": 0.5,
    "amplitude_error": 0.02,
    "leg_phase_error_deg": 0.5,
    "leg_frequency_spread_hz": 0.01,
    "leg_frequency_error_hz": 0.01,  # worst leg: measured vs planned frequency
    "force_rms_relative": 0.01,  # the worst leg's RMS force error / the largest leg's force amplitude
    "off_axis_ratio": 0.01,  # RMS motion across the planned line / amplitude
    "leg_amplitude_error": 0.02,  # worst leg: measured vs |k_i| A
    "active_duration_error_s": 0.06,  # measured vs planned time at >= half amplitude (two 35 Hz periods)
    "sample_ratio_min": 0.99,  # pose / force / wrench estimates per joint state over the run
    "stream_lag_p99_ms": 500.0,  # per node: p99 of its processing lag (the 500-deep queues hold 1 s at 500 Hz)
    # with a tissue model: external-wrench estimate vs the wrench the emulator applied
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
    """The vibration of a vibrate goal: every key of ``vibration.settings.VIBRATION_KEYS`` (the step's values
    over the defaults). What ran is the plan the planner reports, which the summary judges against."""

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
    fracture_site_m: tuple = DEFAULT_FRACTURE_SITE_M  # platform frame (m): where reduction accuracy is reported


def default_scenario_path() -> Path:
    """scenario_paper.yaml in the config directory (``install.default_config_dir``; ConfigError if none)."""
    return default_config_dir() / "scenario_paper.yaml"


SCENARIO_KEYS = {"name", "steps", "bounds", "tissue", "fracture_site_m"}
MAX_STEPS = 1000
MOVE_KINDS = ("move_to", "guarded_move_to")


def load_scenario(robot: Robot, path=None, vibration_duration: float | None = None) -> Scenario:
    """Parse and check a scenario file; ``vibration_duration`` (s) overrides every vibrate step's duration_s.

    Every move's target must be a pose ``robot`` can take (``kinematics.check_pose``), every vibrate step's
    settings pass the planner's check (``vibration.settings.settings_reason``, with the planner's defaults
    for what the step does not set) and end by themselves, every bound is a known one with a finite value
    >= 0, and a tissue file loads.

    Args:
        robot: the robot the scenario runs on.
        path: the scenario YAML; None = config/scenario_paper.yaml.
        vibration_duration: overrides every vibrate step's duration_s (s), or None.

    Returns:
        The Scenario.

    Raises:
        ConfigError: one line naming the file, the step or key and the reason (a file that cannot be read
            safely, a wrong type, an unknown key, an unreachable target, a vibration the planner refuses, a
            bad bound or a bad tissue file).
    """
    path = Path(path).expanduser() if path else default_scenario_path()
    where = f"scenario {path}"
    tree = load_yaml(path, "scenario")
    check_keys(tree, SCENARIO_KEYS, where)
    raw_steps = tree.get("steps")
    if not isinstance(raw_steps, list) or not raw_steps:
        raise ConfigError(f"{where}: needs a non-empty 'steps' list, got {short_repr(raw_steps)}")
    if len(raw_steps) > MAX_STEPS:
        raise ConfigError(f"{where}: {len(raw_steps)} steps, at most {MAX_STEPS}")
    steps: list[MoveStep | VibrateStep] = []
    for index, step in enumerate(raw_steps):
        if not isinstance(step, dict) or len(step) != 1:
            raise ConfigError(f"{where}: step {index} must be one of move_to / guarded_move_to / vibrate, got "
                              f"{short_repr(step)}")
        (kind, value), = step.items()
        if kind in MOVE_KINDS:
            move = _move(robot, value, where, index, kind)
            steps.append(replace(move, name="guarded", guarded=True) if kind == "guarded_move_to" else move)
        elif kind == "vibrate":
            steps.append(VibrateStep(_vibrate(robot, value, where, index, vibration_duration)))
        else:
            raise ConfigError(f"{where}: step {index} has unknown kind {short_repr(kind)} (known: "
                              f"{[*MOVE_KINDS, 'vibrate']})")
    bounds = dict(DEFAULT_BOUNDS)
    given = tree.get("bounds") or {}
    if not isinstance(given, dict):
        raise ConfigError(f"{where}: 'bounds' must be a mapping (name: value lines), got {short_repr(given)}")
    check_keys(given, DEFAULT_BOUNDS, where, "bounds")
    bounds.update({k: as_number(v, f"bounds.{k}", where, BOUND_RANGE) for k, v in given.items()})
    name = tree.get("name", path.stem)
    if not isinstance(name, (str, int, float)) or isinstance(name, bool):
        raise ConfigError(f"{where}: 'name' must be text, got {short_repr(name)}")
    tissue = None
    if tree.get("tissue"):
        if not isinstance(tree["tissue"], str):
            raise ConfigError(f"{where}: 'tissue' must be a file name, got {short_repr(tree['tissue'])}")
        tissue = resolve_tissue_path(tree["tissue"], path.parent)
        load_tissue(tissue, robot)  # a bad tissue file fails here, with its reason, before anything starts
    site = tree.get("fracture_site_m", list(DEFAULT_FRACTURE_SITE_M))
    site = tuple(float(v) for v in as_vector(site, "fracture_site_m", where, 3, FRACTURE_SITE))
    return Scenario(name=str(name), steps=steps, bounds=bounds, source=str(path), tissue=tissue, fracture_site_m=site)


BOUND_RANGE = Plausible(0.0, 1e9)  # a pass/fail bound: finite and >= 0, in the bound's own unit


def _vibrate(robot: Robot, value, where: str, index: int, vibration_duration: float | None) -> dict:
    """A vibrate step's vibration (every VIBRATION_KEYS key: the step's values, the defaults for the rest),
    typed and passed through the planner's check."""
    params = {} if value is None else value
    if not isinstance(params, dict):
        raise ConfigError(f"{where}: step {index} vibrate needs a mapping of planner settings, got "
                          f"{short_repr(value)}")
    check_keys(params, VIBRATE_KEYS, where, f"step {index} vibrate")
    params = dict(params)
    for key, item in params.items():
        if key == "direction":
            params[key] = as_vector(item, f"step {index} vibrate.direction", where, 3).tolist()
        elif key == "frame":
            params[key] = as_choice(item, f"step {index} vibrate.frame", where, FRAMES)
        else:
            params[key] = as_number(item, f"step {index} vibrate.{key}", where)
    if vibration_duration is not None:
        params["duration_s"] = float(vibration_duration)
    settings = {**default_settings(robot), **params}
    if not settings["duration_s"] > 0:
        raise ConfigError(f"{where}: step {index} duration_s must be > 0 (a scenario's vibration must end), got "
                          f"{settings['duration_s']}")
    if reason := settings_reason(robot, settings):
        raise ConfigError(f"{where}: step {index} vibrate: {reason}")
    return {key: settings[key] for key in VIBRATION_KEYS}


def resolve_tissue_path(value, base: Path) -> str:
    """A tissue file named by a scenario or --tissue: as given, beside the scenario (``base``), or in config/.

    Raises:
        ConfigError: no such file in any of the three places.
    """
    given = Path(str(value)).expanduser()
    for candidate in (given, base / given, default_config_dir() / given):
        if candidate.exists():
            return str(candidate.resolve())
    raise ConfigError(f"tissue file {value!r} not found (as given, in {base} or in {default_config_dir()})")


def _move(robot: Robot, value, where: str, index: int, kind: str) -> MoveStep:
    """A move step's target: home, paper or 6 numbers, a pose ``robot`` can take."""
    if value in ("home", "paper"):
        name, pose = str(value), robot.home_pose.copy() if value == "home" else paper_pose(robot)
    elif isinstance(value, list) and len(value) == 6:
        name, pose = "pose", as_vector(value, f"step {index} {kind}", where, 6)
    else:
        raise ConfigError(f"{where}: step {index} {kind} needs paper, home or 6 numbers [x, y, z, roll, pitch, "
                          f"yaw], got {short_repr(value)}")
    try:
        check_pose(robot, pose)
    except StewartError as exc:
        raise ConfigError(f"{where}: step {index} {kind} {value if name != 'pose' else pose.tolist()} cannot be "
                          f"reached by the robot ({robot.source}): {type(exc).__name__}: {exc}") from None
    return MoveStep(name, pose)
