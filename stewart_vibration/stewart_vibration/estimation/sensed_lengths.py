"""The legs' hinge-to-hinge lengths the sensors say, at the states' stamps (pure numpy).

Each leg is a strut (its encoder) and a vibration unit (its own displacement sensor) in series. A unit's sensor
reports the reading of its firmware's last control period, ``unit_sensor_latency_s`` old; at 35 Hz half a
millisecond is 6 deg of phase, and the struts' own small motion is not delayed, so summing the two as
reported turns the sensed vibration's direction (0.6 deg on the realistic plant). The reading is carried
forward by the latency with the rate the unit reports (first order: the error is (w L)^2 / 2 of the
amplitude, 2e-5 at 35 Hz and 0.5 ms).
"""

from __future__ import annotations

import numpy as np


def sensed_leg_lengths(struts: np.ndarray, units: np.ndarray | None, unit_rates: np.ndarray | None,
                       unit_sensor_latency_s: float = 0.0) -> np.ndarray:
    """Strut readings [n, 6] (m) plus the units' displacements [n, 6] (m) carried forward by the latency (s)
    at their reported rates [n, 6] (m/s; NaN or absent rates: not carried). Without units: the struts."""
    if units is None:
        return struts
    lengths = struts + units
    if unit_sensor_latency_s > 0 and unit_rates is not None:
        lengths = lengths + unit_sensor_latency_s * np.nan_to_num(unit_rates, nan=0.0)
    return lengths
