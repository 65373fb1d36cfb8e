"""What a running vibration delivers, seen through the controller's own sensors (pure numpy): the figures
of a vibration session's feedback over its last cycles.

The platform's motion comes from the pose estimate (FK of the measured strut and unit lengths), the legs'
from their measured lengths (the units' sensors, or the lengths the pose estimate implies); nothing here
reads the ground truth.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kinematics.rotations import wrap_angle
from .fits import direction_error_deg, fit_sinusoid, line_of_fit

MIN_CYCLES = 3.0  # fewer cycles in the window: nothing is said (figures 0)
MIN_SAMPLES = 16
SMALL_LEG = 0.05  # a leg planned below this fraction of the largest leg amplitude has no phase to judge


@dataclass(frozen=True)
class DeliveredVibration:
    """The delivered vibration over a window; every figure 0 when the window holds too few cycles."""

    frequency_hz: float  # the strongest frequency of the motion along the planned direction
    amplitude_m: float  # platform amplitude along the planned direction (m)
    direction_error_rad: float  # between the delivered line and the planned direction
    phase_spread_rad: float  # largest distance of a leg's phase error from the legs' mean phase error
    known: bool  # False: the window held too few cycles to say


UNKNOWN = DeliveredVibration(0.0, 0.0, 0.0, 0.0, False)


def _enough(times, frequency: float) -> bool:
    t = np.asarray(times, dtype=float)
    return t.size >= MIN_SAMPLES and (t[-1] - t[0]) * frequency >= MIN_CYCLES


def _frequency_from_phase_drift(times, signal, frequency: float) -> float:
    """The signal's frequency near ``frequency`` (Hz): the phase of a fit at ``frequency`` over the window's
    first and second halves drifts by 2 pi (f - frequency) times the time between their centres (two small
    least squares instead of a search; exact for a pure sine within 1 / (2 x that time) of ``frequency``)."""
    half = times.size // 2
    first, second = fit_sinusoid(times[:half], signal[:half], frequency), fit_sinusoid(times[half:], signal[half:],
                                                                                      frequency)
    spacing = float(times[half:].mean() - times[:half].mean())
    return frequency + float(wrap_angle(second.phase - first.phase)) / (2 * np.pi * spacing)


def delivered_vibration(pose_times, positions, unit_times, unit_positions, frequency: float, direction,
                        leg_amplitudes, leg_phases) -> DeliveredVibration:
    """The vibration the sensors show over a window, against the plan.

    Args:
        pose_times: pose estimate stamps [n] (s).
        positions: the estimated platform positions [n, 3] (m, base frame).
        unit_times: stamps of the legs' samples [m] (s).
        unit_positions: the six legs' measured vibration [m, 6] (m): the units' displacements or the
            hinge-to-hinge lengths (a constant offset does not matter).
        frequency: the planned frequency (Hz).
        direction: the planned direction (3,) (base frame, any non-zero length).
        leg_amplitudes: the planned leg amplitudes [6] (m).
        leg_phases: the planned leg phases [6] (rad, of sin(2 pi f (t - t0) + phase)).

    Returns:
        DeliveredVibration; UNKNOWN when the pose window holds fewer than MIN_CYCLES cycles or MIN_SAMPLES
        samples. The phase spread is 0 when the unit window is that short.
    """
    if not _enough(pose_times, frequency):
        return UNKNOWN
    t = np.asarray(pose_times, dtype=float)
    p = np.asarray(positions, dtype=float)
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)
    fit = fit_sinusoid(t, p, frequency)
    along = float(abs(d @ fit.complex_amplitude))
    line = line_of_fit(fit)  # the same fit: one least squares for the amplitude and the line
    measured_frequency = _frequency_from_phase_drift(t, p @ d, frequency)
    spread = 0.0
    amplitudes = np.asarray(leg_amplitudes, dtype=float)
    judged = amplitudes >= SMALL_LEG * amplitudes.max() if amplitudes.max() > 0 else np.zeros(6, bool)
    if _enough(unit_times, frequency) and judged.any():
        legs = fit_sinusoid(unit_times, unit_positions, frequency)
        # a common phase offset (t0, the sensors' delay) is not a spread: measure about the mean error
        error = wrap_angle(legs.phase[judged] - np.asarray(leg_phases, dtype=float)[judged])
        mean = np.angle(np.exp(1j * error).mean())
        spread = float(np.abs(wrap_angle(error - mean)).max())
    return DeliveredVibration(frequency_hz=float(measured_frequency), amplitude_m=along,
                              direction_error_rad=float(np.radians(direction_error_deg(line.direction, d))),
                              phase_spread_rad=spread, known=True)
