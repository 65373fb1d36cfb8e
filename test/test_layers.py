"""The package's layers (docs/architecture.md, "Layers"): each folder of the pure core imports only the layers
listed before it, and nothing outside nodes/ (and the CLI that starts them) imports rclpy. Parses the sources (no
imports run), so a new cross-layer import or an rclpy import in the core fails here with the file named."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "stewart_vibration" / "stewart_vibration"

# top-level modules first, then the folders in the order they may import one another
TOP = {"errors", "install", "input_checks", "safe_yaml", "config_values", "robot", "paper", "parallel", "splines",
       "rate_limit", "output_files"}
LAYERS = ["<top>", "kinematics", "calibration", "vibration", "sim", "dynamics", "motion", "emulation", "estimation",
          "messages", "mcap_log", "analysis", "runtime", "visualization", "ui", "parameters"]
APPLICATIONS = {"nodes", "cli", "__init__", "__main__"}  # may use every layer
ROS = ("rclpy", "launch", "launch_ros", "rcl_interfaces", "std_srvs", "geometry_msgs", "sensor_msgs",
       "stewart_vibration_interfaces", "action_msgs", "builtin_interfaces")


def layer_of(parts: tuple[str, ...]) -> str:
    if len(parts) == 1:
        name = parts[0].removesuffix(".py")
        return "<top>" if name in TOP else name
    return parts[0]


def imports(package: Path, path: Path):
    """(kind, name, line) of every import in ``path``: ("layer", the package layer) for a relative import,
    ("absolute", the top-level module) otherwise."""
    rel = path.relative_to(package).parts
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom) and node.level > 0:
            target = list(rel[:-1])[: len(rel) - node.level] + (node.module.split(".") if node.module else [])
            if target:
                yield "layer", target[0] if (package / target[0]).is_dir() else layer_of((target[0] + ".py",)), \
                    node.lineno
        elif isinstance(node, ast.ImportFrom) and node.module:
            yield "absolute", node.module.split(".")[0], node.lineno
        elif isinstance(node, ast.Import):
            for alias in node.names:
                yield "absolute", alias.name.split(".")[0], node.lineno


def layer_violations(package: Path) -> list[str]:
    """Every import of the pure core that goes to a later layer, an application or ROS."""
    wrong = []
    for path in sorted(package.rglob("*.py")):
        own = layer_of(path.relative_to(package).parts)
        if own in APPLICATIONS:
            continue
        where = path.relative_to(package.parent)
        if own not in LAYERS:
            wrong.append(f"{where}: layer {own!r} is not in LAYERS (add it where it belongs)")
            continue
        for kind, target, line in imports(package, path):
            if kind == "layer" and target != own and (target in APPLICATIONS or target not in LAYERS or
                                                      LAYERS.index(target) > LAYERS.index(own)):
                wrong.append(f"{where}:{line} ({own}) imports {target}")
            elif kind == "absolute" and target in ROS:
                wrong.append(f"{where}:{line} ({own}) imports {target} (ROS)")
    return wrong


def test_each_layer_imports_only_the_layers_before_it():
    wrong = layer_violations(PACKAGE)
    assert not wrong, "\n".join(wrong)


def test_the_check_sees_a_wrong_import(tmp_path):
    """The check itself can fail: a kinematics module importing the run summary and rclpy is reported."""
    fake = tmp_path / "stewart_vibration"
    (fake / "kinematics").mkdir(parents=True)
    (fake / "analysis").mkdir()
    (fake / "analysis" / "run_summary.py").write_text("from ..kinematics import ik\n")
    (fake / "kinematics" / "bad.py").write_text("from ..analysis.run_summary import check_bounds\nimport rclpy\n")
    assert layer_violations(fake) == ["stewart_vibration/kinematics/bad.py:1 (kinematics) imports analysis",
                                      "stewart_vibration/kinematics/bad.py:2 (kinematics) imports rclpy (ROS)"]
