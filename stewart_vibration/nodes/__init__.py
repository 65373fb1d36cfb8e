"""ROS 2 node adapters (the only part of the package that imports rclpy).

Importing this package makes sure ament_index finds the interface packages
installed by pip into the running interpreter's prefix (see DESIGN.md).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path


def ensure_ament_prefix_path() -> None:
    """Prepend sys.prefix to AMENT_PREFIX_PATH when it holds an ament index (pip world)."""
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    if sys.prefix not in prefixes and (Path(sys.prefix) / "share" / "ament_index").is_dir():
        os.environ["AMENT_PREFIX_PATH"] = os.pathsep.join([sys.prefix, *prefixes])


ensure_ament_prefix_path()
