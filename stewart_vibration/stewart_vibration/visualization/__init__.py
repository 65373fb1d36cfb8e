"""Views of the robot as plain data (no rclpy, no Foxglove): the 3D scene the Foxglove bridge
publishes and the offline renderer draws. See ``scene``."""

from . import scene
from .scene import *  # noqa: F403 - the scene's public names

__all__ = scene.__all__
