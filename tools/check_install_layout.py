"""Check a colcon install tree of stewart_vibration (used by .ci/run).

Usage: python tools/check_install_layout.py INSTALL_BASE
Verifies lib/stewart_vibration/<every console script in setup.py>, the ament
index marker, share/stewart_vibration/package.xml, every config file, the
launch files and the planning UI's page (package data); exits non-zero listing what is missing.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGE = "stewart_vibration"


def console_scripts() -> list[str]:
    """Executable names from CONSOLE_SCRIPTS in setup.py (parsed, not executed)."""
    tree = ast.parse((REPO / "setup.py").read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign) and any(getattr(t, "id", "") == "CONSOLE_SCRIPTS" for t in node.targets):
            return [ast.literal_eval(elt).split("=")[0].strip() for elt in node.value.elts]
    raise SystemExit("setup.py has no CONSOLE_SCRIPTS list")


def main() -> int:
    install = Path(sys.argv[1]) / PACKAGE
    expected = [install / "lib" / PACKAGE / exe for exe in console_scripts()]
    expected += [
        install / "share/ament_index/resource_index/packages" / PACKAGE,
        install / "share" / PACKAGE / "package.xml",
    ]
    config = [p for pattern in ("*.yaml", "*.xml", "*.json") for p in sorted((REPO / "config").glob(pattern))]
    expected += [install / "share" / PACKAGE / "config" / p.name for p in config]
    # package data: the planning UI's page, beside the installed modules (lib/python3.X/site-packages)
    site = sorted((install / "lib").glob("python3*/site-packages"))
    ui_static = sorted((REPO / PACKAGE / "ui" / "static").iterdir())
    if site:
        expected += [site[0] / PACKAGE / "ui" / "static" / p.name for p in ui_static]
    else:
        expected.append(install / "lib" / "python3.X" / "site-packages")
    expected += [install / "share" / PACKAGE / "launch" / p.name for p in sorted((REPO / "launch").glob("*.launch.py"))]
    missing = [str(p) for p in expected if not p.exists()]
    for path in expected:
        print(("ok      " if path.exists() else "MISSING ") + str(path.relative_to(install)))
    if missing:
        print(f"{len(missing)} installed file(s) missing", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
