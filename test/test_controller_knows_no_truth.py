"""The rule of the emulator, read from the source: the controller nodes (kinematics, planner, estimator,
planning UI) name no ground_truth/ topic in their code, and nothing in their in-package import closure is
the plant (emulation.plant) or the emulator; the emulator node's own source does both (the check can see)."""

from __future__ import annotations

import ast
import importlib.util

CONTROLLERS = ("kinematics_node", "vibration_planner_node", "leg_force_estimator_node", "planning_ui_node")
PACKAGE = "stewart_vibration"
TRUTH_ONLY = {f"{PACKAGE}.emulation.plant", f"{PACKAGE}.emulation.emulator"}  # the robot as built


def _imports(module: str) -> set[str]:
    """The in-package modules ``module``'s source imports (absolute and relative)."""
    spec = importlib.util.find_spec(module)
    assert spec is not None and spec.origin is not None, module
    tree = ast.parse(open(spec.origin).read())
    package = module if spec.submodule_search_locations else module.rsplit(".", 1)[0]
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.startswith(PACKAGE)}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[:len(parts) - node.level + 1] + ([base] if base else []))
            if not base.startswith(PACKAGE):
                continue
            for alias in node.names:
                candidate = f"{base}.{alias.name}"
                found.add(candidate if importlib.util.find_spec(base) and _is_module(candidate) else base)
    return found


def _is_module(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except (ImportError, ValueError):
        return False


def closure(module: str) -> set[str]:
    seen, todo = set(), [module]
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        todo += sorted(_imports(name) - seen)
    return seen


def _source(module: str) -> str:
    spec = importlib.util.find_spec(module)
    assert spec is not None and spec.origin is not None
    return open(spec.origin).read()


def truth_topics_named(module: str) -> list[str]:
    """The string constants of ``module``'s code (docstrings aside) that name a ground_truth/ topic."""
    tree = ast.parse(_source(module))
    docstrings = {id(n.body[0].value) for n in ast.walk(tree)
                  if isinstance(n, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and n.body
                  and isinstance(n.body[0], ast.Expr) and isinstance(n.body[0].value, ast.Constant)}
    return [n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and isinstance(n.value, str)
            and "ground_truth/" in n.value and id(n) not in docstrings]


def test_no_controller_node_names_a_ground_truth_topic_or_imports_the_plant():
    for node in CONTROLLERS:
        module = f"{PACKAGE}.nodes.{node}"
        modules = closure(module)
        assert f"{PACKAGE}.robot" in modules  # the walk follows the imports
        assert not modules & TRUTH_ONLY, (node, sorted(modules & TRUTH_ONLY))
        assert truth_topics_named(module) == [], node


def test_the_check_sees_the_emulator_read_the_plant_and_publish_the_truth():
    module = f"{PACKAGE}.nodes.hardware_emulator_node"
    assert f"{PACKAGE}.emulation.plant" in closure(module)
    assert set(truth_topics_named(module)) == {"ground_truth/joint_states", "ground_truth/platform_pose",
                                                "ground_truth/tissue_wrench"}
