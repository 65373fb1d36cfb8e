"""The servos' references on the physics step grid (no rclpy): what the drives are told to follow, from the
safety controller's commanded strut trajectory and vibration buffer (m, m/s, m/s^2 per leg).

The references are sampled for a horizon at a time in one vectorised call and reused until a command changes
them (the safety controller's ``version``).
"""

from __future__ import annotations

import numpy as np

from .safety_controller import SafetyController


class ServoReferences:
    """The cached references of ``safety``'s commanded motion (``sample``)."""

    _refs: tuple[int, float, tuple[np.ndarray, ...]] | None

    def __init__(self, safety: SafetyController):
        self.safety = safety
        self._refs = None  # (version, first step time, arrays) of the sampled references

    def sample(self, time: float, steps: int, dt: float, horizon_s: float):
        """(lengths, rates at t - dt/2, accelerations, vib positions, vib velocities) [steps + 1, 6] at the
        step times time + k dt, k = 0..steps (the last row is the block's end), from the cache (sampled again
        for ``horizon_s`` at a time once a command changed or the cache ran out).

        The servos' references come from the commanded hinge lengths L (strut + vibration) on the step
        grid: the acceleration of step k is the second difference (L[k+1] - 2 L[k] + L[k-1]) / dt^2 and
        the rate (L[k] - L[k-1]) / dt, the values with which semi-implicit Euler reproduces L at every
        step (its velocities live half a step back)."""
        cache = self._refs
        if cache is not None and cache[0] == self.safety.version:
            first = int(round((time - cache[1]) / dt))
            if 0 <= first and first + steps < len(cache[2][0]):
                return tuple(a[first:first + steps + 1] for a in cache[2])
        count = max(steps, int(round(horizon_s / dt))) + 1
        t = time + dt * np.arange(-1, count + 1)  # one step before and after for the differences
        strut = self.safety.struts.sample(t)[0]
        vib, vib_rate, _ = self.safety.vibration.sample(t)
        length = strut + vib
        accel = (length[2:] - 2.0 * length[1:-1] + length[:-2]) / dt**2
        rates_half = (length[1:-1] - length[:-2]) / dt
        arrays = (length[1:-1], rates_half, accel, vib[1:-1], vib_rate[1:-1])
        self._refs = (self.safety.version, time, arrays)
        return tuple(a[:steps + 1] for a in arrays)
