"""ROS 2 node adapters (the only part of the package that imports rclpy).

Importing this package makes sure ament_index finds the interface packages
installed by pip into the running interpreter's prefix (see docs/architecture.md).
"""

from __future__ import annotations

import os

from ..install import prepend_interpreter_prefix


def ensure_ament_prefix_path() -> None:
    """Prepend sys.prefix to AMENT_PREFIX_PATH when it holds an ament index (pip world)."""
    prepend_interpreter_prefix(os.environ, require_ament_index=True)


ensure_ament_prefix_path()
