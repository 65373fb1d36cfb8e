"""The vibration planner's streaming settings as the planning page knows them (pure): its defaults until the
planner answers get_parameters, and the ranges it declares, for the preview's and the start's checks (SI units)."""

from __future__ import annotations

from dataclasses import dataclass, field

from ..robot import Robot
from ..vibration.settings import STREAM_KEYS, default_settings
from . import model


@dataclass
class PlannerSettings:
    """``values``: the streaming settings (STREAM_KEYS); ``known``: the planner's own values came (until then
    the defaults stand in, and the page is told); ``ranges``: {name: (low, high)} the planner declares."""

    values: dict
    known: bool = False
    ranges: dict = field(default_factory=dict)

    @classmethod
    def defaults(cls, robot: Robot) -> PlannerSettings:
        """The planner's defaults for ``robot``, not known to be its values yet."""
        return cls(model.stream_defaults(robot))

    def got(self, settings: dict) -> None:
        """The planner's answer (its streaming settings; anything else in it is ignored)."""
        self.values.update({k: v for k, v in settings.items() if k in STREAM_KEYS})
        self.known = True

    def declared(self, ranges: dict) -> None:
        """The ranges {name: (low, high)} the planner declares for its parameters."""
        self.ranges = ranges

    def vibration(self, robot: Robot, fields: dict) -> tuple[dict, dict]:
        """(the page's vibration ``fields`` as the planner's parameters, every setting with it: the planner's
        streaming settings and the defaults of what the page left out)."""
        params = model.vibration_from_fields(fields)
        return params, {**default_settings(robot), **self.values, **params}
