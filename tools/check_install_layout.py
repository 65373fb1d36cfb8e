"""Check a colcon install tree of stewart_vibration and stewart_vibration_interfaces (used by .ci/run).

Usage: python tools/check_install_layout.py INSTALL_BASE
Verifies lib/stewart_vibration/<every console script in setup.py>, the ament
index marker, share/stewart_vibration/package.xml, every config file, the
launch files and the planning UI's page (package data); and of the interfaces package, every
.msg/.srv/.action file under share/, its rosidl_interfaces index entry and their Python modules. Exits
non-zero listing what is missing.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

PACKAGE = "stewart_vibration"
PACKAGE_DIR = Path(__file__).resolve().parents[1] / PACKAGE  # setup.py, config/, launch/ and the module
INTERFACES = "stewart_vibration_interfaces"
INTERFACES_DIR = Path(__file__).resolve().parents[1] / INTERFACES  # its .msg, .srv and .action files


def console_scripts() -> list[str]:
    """Executable names from CONSOLE_SCRIPTS in setup.py (parsed, not executed)."""
    tree = ast.parse((PACKAGE_DIR / "setup.py").read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign) and any(getattr(t, "id", "") == "CONSOLE_SCRIPTS" for t in node.targets):
            return [ast.literal_eval(elt).split("=")[0].strip() for elt in node.value.elts]
    raise SystemExit("setup.py has no CONSOLE_SCRIPTS list")


def python_expected(install: Path) -> list[Path]:
    """What the ament_python package installs: its executables, ament index marker, package.xml, config,
    launch files and the planning UI's page."""
    expected = [install / "lib" / PACKAGE / exe for exe in console_scripts()]
    expected += [
        install / "share/ament_index/resource_index/packages" / PACKAGE,
        install / "share" / PACKAGE / "package.xml",
    ]
    config = [p for pattern in ("*.yaml", "*.xml", "*.json") for p in sorted((PACKAGE_DIR / "config").glob(pattern))]
    expected += [install / "share" / PACKAGE / "config" / p.name for p in config]
    # package data: the planning UI's page, beside the installed modules (lib/python3.X/site-packages)
    site = sorted((install / "lib").glob("python3*/site-packages"))
    ui_static = sorted((PACKAGE_DIR / PACKAGE / "ui" / "static").iterdir())
    if site:
        expected += [site[0] / PACKAGE / "ui" / "static" / p.name for p in ui_static]
    else:
        expected.append(install / "lib" / "python3.X" / "site-packages")
    launch = sorted((PACKAGE_DIR / "launch").glob("*.launch.py"))
    return expected + [install / "share" / PACKAGE / "launch" / p.name for p in launch]


def interfaces_expected(install: Path) -> list[Path]:
    """What the interfaces package installs: every .msg/.srv/.action under share/ (what ``ros2 interface show``
    reads), its rosidl_interfaces index entry, and a generated Python module per interface."""
    expected = [install / "share/ament_index/resource_index/rosidl_interfaces" / INTERFACES,
                install / "share" / INTERFACES / "package.xml"]
    site = sorted((install / "lib").glob("python3*/site-packages"))
    for kind in ("msg", "srv", "action"):
        for source in sorted((INTERFACES_DIR / kind).glob(f"*.{kind}")):
            expected.append(install / "share" / INTERFACES / kind / source.name)
            module = "_" + "".join("_" + c.lower() if c.isupper() else c for c in source.stem).lstrip("_") + ".py"
            expected.append((site[0] if site else install / "lib/python3.X/site-packages") / INTERFACES / kind / module)
    return expected


def main() -> int:
    base = Path(sys.argv[1])
    expected = python_expected(base / PACKAGE) + interfaces_expected(base / INTERFACES)
    missing = [str(p) for p in expected if not p.exists()]
    for path in expected:
        print(("ok      " if path.exists() else "MISSING ") + str(path.relative_to(base)))
    if missing:
        print(f"{len(missing)} installed file(s) missing", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
