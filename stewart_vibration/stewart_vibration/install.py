"""Where this package's files and the ROS interface packages are (no rclpy): the one place the ament
prefixes are looked up.

In a venv (the pip world) rclpy works as installed, but ament_index needs the interpreter's prefix
(``sys.prefix``) on $AMENT_PREFIX_PATH to find the interface packages pip put there (docs/architecture.md). On a
ROS install, colcon's setup scripts set $AMENT_PREFIX_PATH and the package's config lives in
``<prefix>/share/stewart_vibration/config``; in a checkout or an editable install it is the source
tree's ``config/``.
"""

from __future__ import annotations

import os
import sys
from collections.abc import MutableMapping
from pathlib import Path

from .errors import ConfigError

PACKAGE = "stewart_vibration"
CONFIG_DIR_ENV = "STEWART_VIBRATION_CONFIG_DIR"  # overrides where robot.yaml and the scenarios are read


def install_prefixes(environ=None) -> list[str]:
    """Install prefixes to search for ``share/<package>``, in order: $AMENT_PREFIX_PATH, then sys.prefix.

    Args:
        environ: the environment to read (default: os.environ).

    Returns:
        The prefixes, without duplicates.
    """
    environ = os.environ if environ is None else environ
    prefixes = [p for p in environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    return list(dict.fromkeys([*prefixes, sys.prefix]))


def prepend_interpreter_prefix(environ: MutableMapping[str, str], require_ament_index: bool = False) -> None:
    """Put sys.prefix first on $AMENT_PREFIX_PATH of ``environ`` unless it is already on it.

    Args:
        environ: the environment to change (os.environ, or a child process's).
        require_ament_index: only if sys.prefix holds an ament index (share/ament_index: the pip world's
            venv with the interface packages).
    """
    prefixes = [p for p in environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    if sys.prefix in prefixes:
        return
    if require_ament_index and not (Path(sys.prefix) / "share" / "ament_index").is_dir():
        return
    environ["AMENT_PREFIX_PATH"] = os.pathsep.join([sys.prefix, *prefixes])


def config_dirs() -> list[Path]:
    """Where the package's config files may be, in search order: $STEWART_VIBRATION_CONFIG_DIR (if set),
    the source tree's config/ (a checkout or an editable install), then ``share/stewart_vibration/config``
    of every install prefix."""
    dirs = [Path(os.environ[CONFIG_DIR_ENV])] if os.environ.get(CONFIG_DIR_ENV) else []
    dirs.append(Path(__file__).resolve().parent.parent / "config")
    dirs += [Path(p) / "share" / PACKAGE / "config" for p in install_prefixes()]
    return dirs


def find_config_file(name: str, dirs=None) -> Path:
    """The first ``name`` in ``dirs`` (default: ``config_dirs()``), resolved.

    Raises:
        FileNotFoundError: naming every place searched.
    """
    candidates = config_dirs() if dirs is None else [Path(d) for d in dirs]
    for directory in candidates:
        if (directory / name).is_file():
            return (directory / name).resolve()
    raise FileNotFoundError(f"cannot find {name} in " + ", ".join(str(d) for d in candidates))


def config_path(value) -> Path:
    """A config file a user names: the path as given, or, when it is relative and no such file exists, the
    same name in ``default_config_dir()`` if it is there (e.g. ``tissue.yaml``). ConfigError as
    ``default_config_dir`` when that is needed and not found."""
    path = Path(value).expanduser()
    if not path.exists() and not path.is_absolute() and (default_config_dir() / path).exists():
        path = default_config_dir() / path
    return path


def default_config_dir() -> Path:
    """The directory holding robot.yaml, the scenarios and the node parameters.

    $STEWART_VIBRATION_CONFIG_DIR when set (as given, even without robot.yaml: a bad setting is then said
    where robot.yaml is read), else the first of ``config_dirs()`` with a robot.yaml.

    Raises:
        ConfigError: no robot.yaml anywhere.
    """
    if os.environ.get(CONFIG_DIR_ENV):
        return Path(os.environ[CONFIG_DIR_ENV])
    try:
        return find_config_file("robot.yaml").parent
    except FileNotFoundError:
        raise ConfigError(f"cannot find config/robot.yaml; set {CONFIG_DIR_ENV}") from None
