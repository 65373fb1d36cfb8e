"""A tissue model (``tissue.TissueModel``) from its YAML file (config/tissue.yaml): every value checked against
its plausible range (SI: N/m, N s/m, N m/rad, N m s/rad, N, m), the rest pose (m, rad, base frame) one the robot
can take and the worst-case wrench within the bound (``tissue_bounds``); ConfigError naming the key otherwise.
"""

from __future__ import annotations

import numpy as np

from ..config_values import Plausible, as_number, as_vector, check_keys, lookup
from ..errors import ConfigError, StewartError
from ..install import config_path
from ..kinematics import check_pose
from ..paper import paper_pose
from ..robot import Robot
from ..safe_yaml import load_yaml, short_repr
from .tissue import TissueModel
from .tissue_bounds import check_tissue_wrench

STIFFENING_TYPES = ("none", "exponential", "piecewise_linear")
_KEYS = {"name", "note", "rest_pose", "center_m", "axial", "lateral", "torsional", "bending", "preload_n",
         "stiffening"}

# Plausible ranges of the tissue file's values (SI). Soft tissue around a long-bone fracture is of the
# order of 10 N/mm and a few N m per 10 deg; these allow two orders of magnitude more, and a stiffening
# length of at least 1 mm (the exponential spring grows e-fold per length_m: shorter makes it a wall).
_PLAUSIBLE = {
    "stiffness_n_m": Plausible(0.0, 1e6, "N/m"),
    "damping_n_s_m": Plausible(0.0, 1e4, "N s/m"),
    "stiffness_nm_rad": Plausible(0.0, 1e4, "N m/rad"),
    "damping_nm_s_rad": Plausible(0.0, 100.0, "N m s/rad"),
    "preload_n": Plausible(0.0, 1e3, "N"),
    "center_m": Plausible(-0.5, 0.5, "m"),
    "length_m": Plausible(1e-3, 1.0, "m"),
    "breakpoints_m": Plausible(0.0, 0.5, "m"),
    "slopes_n_m": Plausible(0.0, 1e6, "N/m"),
}


def _number(tree: dict, key: str, where: str, kind: str | None = None) -> float:
    """The number at ``tree[key]`` in its plausible range (``kind``: the range's name, default the key)."""
    if not isinstance(tree, dict) or key not in tree:
        raise ConfigError(f"{where}: missing field '{key}'")
    return as_number(tree[key], key, where, _PLAUSIBLE[kind or key])


def _pair(tree: dict, key: str, units: tuple[str, str], where: str) -> tuple[float, float]:
    stiffness, damping = f"stiffness_{units[0]}", f"damping_{units[1]}"
    part = tree.get(key)
    if not isinstance(part, dict):
        raise ConfigError(f"{where}: '{key}' needs {stiffness} and {damping}, got {short_repr(part)}")
    check_keys(part, {stiffness, damping}, where, key)
    return (as_number(lookup(tree, f"{key}.{stiffness}", where), f"{key}.{stiffness}", where, _PLAUSIBLE[stiffness]),
            as_number(lookup(tree, f"{key}.{damping}", where), f"{key}.{damping}", where, _PLAUSIBLE[damping]))


def resolve_pose(robot: Robot, value, key: str, where: str) -> np.ndarray:
    """``home``, ``paper`` or 6 numbers [x, y, z, roll, pitch, yaw] (m, rad) -> pose (6,).

    Args:
        robot: the robot (its home pose and the paper pose).
        value: "home", "paper", or a list of six numbers (m, rad).
        key: the value's key, for the error message.
        where: the file, for the error message.

    Returns:
        The pose (6,) (m, rad), a new array.

    Raises:
        ConfigError: naming ``key``: ``value`` is neither "home", "paper" nor a list of six finite numbers.
    """
    if value == "home":
        return robot.home_pose.copy()
    if value == "paper":
        return paper_pose(robot)
    if not (isinstance(value, list) and len(value) == 6):
        raise ConfigError(f"{where}: '{key}' needs home, paper or 6 numbers [x, y, z, roll, pitch, yaw], got "
                          f"{short_repr(value)}")
    return as_vector(value, key, where, 6)


def _stiffening(tree: dict, k_axial: float, where: str) -> tuple[str, float, np.ndarray | None, np.ndarray | None]:
    """(type, length_m, breakpoints_m, slopes) of the ``stiffening`` section."""
    stiff = tree.get("stiffening") or {"type": "none"}
    if not isinstance(stiff, dict) or stiff.get("type", "none") not in STIFFENING_TYPES:
        raise ConfigError(f"{where}: 'stiffening.type' must be one of {list(STIFFENING_TYPES)}, got "
                          f"{short_repr(stiff.get('type') if isinstance(stiff, dict) else stiff)}")
    kind = stiff.get("type", "none")
    allowed = {"none": {"type"}, "exponential": {"type", "length_m"},
               "piecewise_linear": {"type", "breakpoints_m", "stiffness_n_m"}}[kind]
    check_keys(stiff, allowed, where, f"stiffening ({kind})")
    if kind == "exponential":
        return kind, as_number(lookup(stiff, "length_m", where), "stiffening.length_m", where,
                               _PLAUSIBLE["length_m"]), None, None
    if kind == "piecewise_linear":
        starts, slopes = (lookup(stiff, key, where) for key in ("breakpoints_m", "stiffness_n_m"))
        count = len(starts) if isinstance(starts, list) else 0
        if not 1 <= count <= 100:
            raise ConfigError(f"{where}: 'stiffening.breakpoints_m' must be a list of 1 to 100 numbers, got "
                              f"{short_repr(starts)}")
        starts = as_vector(starts, "stiffening.breakpoints_m", where, count, _PLAUSIBLE["breakpoints_m"])
        slopes = as_vector(slopes, "stiffening.stiffness_n_m", where, count, _PLAUSIBLE["slopes_n_m"])
        if starts[0] != 0.0 or (np.diff(starts) <= 0).any() or slopes[0] != k_axial:
            raise ConfigError(f"{where}: piecewise_linear needs breakpoints_m strictly increasing from 0 and as "
                              "many stiffness_n_m >= 0, the first equal to axial.stiffness_n_m")
        return kind, 0.0, starts, slopes
    return kind, 0.0, None, None


def tissue_from_dict(tree: dict, robot: Robot, source: str = "<dict>") -> TissueModel:
    """Build a TissueModel from the parsed YAML tree (see config/tissue.yaml); ConfigError with the reason.

    Every value is checked against its plausible range (``_PLAUSIBLE``), the rest pose must be one the
    robot can take (``kinematics.check_pose``), and the worst-case wrench near the rest pose must stay
    within the plausible bound and finite within the robot's reach (``check_tissue_wrench``).

    Args:
        tree: the parsed YAML mapping (keys name, note, rest_pose, center_m, axial, lateral, torsional,
            bending, preload_n, stiffening).
        robot: the robot (for rest_pose "home" / "paper", its reach and its strut limits).
        source: where the tree comes from, for error messages and ``TissueModel.source``.

    Returns:
        The TissueModel (SI units).

    Raises:
        ConfigError: one line naming the key: the tree is not a mapping, has unknown keys, a missing,
            mistyped, non-finite or implausible value, a rest pose the robot cannot take, a bad stiffening
            section, or a worst-case wrench beyond the bound.
    """
    where = f"tissue config {source}"
    if not isinstance(tree, dict):
        raise ConfigError(f"{where}: top level must be a mapping")
    check_keys(tree, _KEYS, where)
    rest = resolve_pose(robot, tree.get("rest_pose", "home"), "rest_pose", where)
    try:
        check_pose(robot, rest)
    except StewartError as exc:
        raise ConfigError(f"{where}: 'rest_pose' {rest.tolist()} cannot be taken by the robot: "
                          f"{type(exc).__name__}: {exc}") from None
    center = as_vector(tree.get("center_m", [0.0, 0.0, 0.0]), "center_m", where, 3, _PLAUSIBLE["center_m"])
    k_ax, c_ax = _pair(tree, "axial", ("n_m", "n_s_m"), where)
    k_lat, c_lat = _pair(tree, "lateral", ("n_m", "n_s_m"), where)
    k_tor, c_tor = _pair(tree, "torsional", ("nm_rad", "nm_s_rad"), where)
    k_bend, c_bend = _pair(tree, "bending", ("nm_rad", "nm_s_rad"), where)
    preload = _number(tree, "preload_n", where) if "preload_n" in tree else 0.0
    kind, length, starts, slopes = _stiffening(tree, k_ax, where)
    for key in ("name", "note"):
        if not isinstance(tree.get(key, ""), str):
            raise ConfigError(f"{where}: '{key}' must be text, got {short_repr(tree[key])}")
    model = TissueModel(
        rest_pose=rest, center=center,
        stiffness=np.array([k_lat, k_lat, k_ax, k_bend, k_bend, k_tor]),
        damping=np.array([c_lat, c_lat, c_ax, c_bend, c_bend, c_tor]),
        preload=preload, stiffening=kind, length_m=length, breakpoints_m=starts, slopes_n_m=slopes,
        name=str(tree.get("name", "tissue")), source=source)
    check_tissue_wrench(model, robot, where)
    return model


def load_tissue(path, robot: Robot) -> TissueModel:
    """Tissue model from a YAML file; a bare file name is looked up in the config directory too.

    Args:
        path: the YAML file (str or Path); a relative path that is not a file is tried in
            ``default_config_dir()``.
        robot: the robot (for rest_pose "home" / "paper").

    Returns:
        The TissueModel.

    Raises:
        ConfigError: the file cannot be read safely (``safe_yaml.load_yaml``), a value is bad
            (``tissue_from_dict``), or the config directory is needed and not found (``default_config_dir``).
    """
    path = config_path(path)
    return tissue_from_dict(load_yaml(path, "tissue config"), robot, str(path))


def load_tissue_option(value: str | None, robot: Robot) -> TissueModel | None:
    """A node's ``tissue_config`` parameter: '' (or None) = no tissue, else ``load_tissue``.

    Args:
        value: the parameter: a YAML path, '' or None.
        robot: the robot.

    Returns:
        The TissueModel, or None for '' / None.

    Raises:
        ConfigError: as ``load_tissue``.
    """
    return load_tissue(value, robot) if value else None


__all__ = [
    "STIFFENING_TYPES",
    "load_tissue",
    "load_tissue_option",
    "resolve_pose",
    "tissue_from_dict",
]
