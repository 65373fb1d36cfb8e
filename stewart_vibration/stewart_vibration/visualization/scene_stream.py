"""What a live scene sends at each tick (pure; the Foxglove bridge node feeds it and publishes what it returns):
the scene at the latest pose, the vibration arrow while the robot's units are busy with a vibration, the arrow's
deletion once it ends, and the static entities (base, platform) only every ``static_period_s`` so a client that
joins later still gets them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import scene as scene_model

# vibration/status states in which a vibration is planned or under way (emulation.vibration_status)
VIBRATING_STATES = frozenset({"pending", "ramping_in", "running", "ramping_out"})


@dataclass(frozen=True)
class SceneFrame:
    """One tick's output: the scene, the entities to send (static ones left out between their periods) and
    whether the vibration arrow must be deleted (it was shown, the vibration ended)."""

    scene: scene_model.Scene
    entities: tuple
    delete_arrow: bool


class SceneStream:
    """The scene's state between ticks: the robot's vibration state, the latest planned window (its arrow's
    direction is computed once per window, at the next tick's pose), what the client was last sent."""

    def __init__(self, builder: scene_model.SceneBuilder, static_period_s: float):
        self.builder, self.static_period_s = builder, static_period_s
        self.vibrating = False
        self._window: np.ndarray | None = None  # latest planned vib_1..6 samples (n, 6), m
        self._direction: np.ndarray | None = None
        self._direction_stale = False
        self._arrow_shown = False
        self._static_sent = float("-inf")  # steady time (s) the static entities were last sent

    def on_status(self, state: str) -> None:
        """The robot's vibration/status state."""
        self.vibrating = state in VIBRATING_STATES

    def on_window(self, vib_positions: np.ndarray) -> None:
        """A planned window's vib_1..6 samples (n >= 2, 6), m."""
        self._window = vib_positions
        self._direction_stale = True

    def unwatched(self) -> None:
        """No client watches: the next one starts from a clean scene (static entities sent, no arrow)."""
        self._arrow_shown = False
        self._static_sent = float("-inf")

    def frame(self, position, quaternion, stamp: float, now: float) -> SceneFrame:
        """The tick at the pose (position m, quaternion x y z w, base frame; ``stamp`` s) at steady time ``now``
        (s)."""
        if self._direction_stale and self._window is not None:
            self._direction = scene_model.vibration_direction_from_window(self.builder.robot, position, quaternion,
                                                                          self._window)
            self._direction_stale = False
        direction = self._direction if self.vibrating else None
        scene = self.builder.scene(position, quaternion, stamp, direction)
        entities = scene.entities
        if now - self._static_sent < self.static_period_s:
            entities = tuple(e for e in entities if e.id not in scene_model.STATIC_ENTITIES)
        else:
            self._static_sent = now
        delete_arrow = direction is None and self._arrow_shown
        self._arrow_shown = direction is not None
        return SceneFrame(scene, entities, delete_arrow)
