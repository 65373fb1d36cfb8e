"""The vibration units' travel limit, as a unit's own firmware enforces it (pure numpy, no ROS).

A resonant unit driven near or above its resonance moves more than it is told to (on the realistic plant an
uncompensated 61 um demand drove a unit to ~120 um), and its end stops are at the unit's travel
(``robot.vibration_unit.amplitude_max``, 100 um). The robot must not rely on its controller to prevent that:
each block of physics steps the emulator gives the units' sensor readings to ``UnitTravelGuard``, which
trips once when a reading leaves the travel, naming the unit, its reading and the limit. The emulator then
ramps the vibration out (a safety ramp whose reason is ``UNIT_OVER_TRAVEL``; the struts keep their
commands). The guard re-arms when every unit is back within the travel.
"""

from __future__ import annotations

import numpy as np

from ..robot import VIB_NAMES

UNIT_OVER_TRAVEL = "unit over-travel"  # the reason of the safety ramp the guard starts


class UnitTravelGuard:
    """Trips on the first block whose unit readings leave +-``travel_m`` (m); see the module docstring."""

    def __init__(self, travel_m: float):
        if not np.isfinite(travel_m) or travel_m <= 0:
            raise ValueError(f"unit travel must be a positive number of metres, got {travel_m!r}")
        self.travel_m = float(travel_m)
        self.armed = True
        self.trips = 0

    def check(self, readings) -> str | None:
        """The trip's reason when ``readings`` (6,) (m, each unit's sensor) leave the travel while armed (the
        worst unit named, um), else None. A non-finite reading counts as outside the travel."""
        values = np.abs(np.asarray(readings, float))
        outside = ~(values <= self.travel_m)  # NaN counts as outside
        if not outside.any():
            self.armed = True
            return None
        if not self.armed:
            return None
        self.armed = False
        self.trips += 1
        worst = int(np.nanargmax(np.where(np.isfinite(values), values, np.inf)))
        return (f"{UNIT_OVER_TRAVEL}: {VIB_NAMES[worst]} read {values[worst] * 1e6:.1f} um, travel "
                f"+-{self.travel_m * 1e6:.1f} um; vibration ramped out")
