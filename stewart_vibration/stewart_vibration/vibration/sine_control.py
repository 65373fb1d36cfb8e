"""Closed-loop sine control of the delivered platform vibration (pure numpy), as a multi-axis vibration
table controller does it: the six legs' complex demands are corrected from the measured 6-DOF response at the
drive frequency until the platform moves as targeted, within tolerance bands, and the vibration is aborted
when the response leaves its abort limits.

Vectors: demands u (6,) complex, m per leg (x = |c| sin(2 pi f t + arg c)); platform responses y (6,)
complex [dp (m); dphi (rad)], base frame, platform origin; the plant estimate H (6, 6) complex maps u to y
(vibration.unit_identification, or the kinematic map J^-1 of an ideal robot). Rotations are weighed by
``rotation_scale_m`` (a rotation of 1 rad counts as that many metres) wherever a translation and a rotation
are compared.

The iteration u <- u + mu H^-1 (y* - y) on a plant P converges when every eigenvalue g of P H^-1 lies
where the loop's characteristic polynomial is stable: with the measurement of update k showing the demand
of update k - d, z^(d+1) - z^d + mu g = 0 must have all roots inside the unit circle
(``iteration_spectral_radius``). For d = 0 that is |1 - mu g| < 1, and the error shrinks by |1 - mu g| per
update. For mu = 0.5 the loop is stable, without delay, for plant/estimate gain ratios up to 4 at zero phase
error and for phase errors up to 75 deg at the nominal gain; with one update of delay (a correction acts
after the next measurement) for ratios up to 2 and phase errors up to 46 deg. Over unit errors of +-30 % gain
and +-20 deg phase the worst rate per update is 0.68 (mu = 0.5) or 0.81 (mu = 0.3) without delay, and 0.92
(mu = 0.5) or 0.78 (mu = 0.3) with one update of delay (the test suite checks these figures). The streamed loop
(``closed_loop``) measures only periods after a correction has blended in, so it runs without delay and
DEFAULT_LOOP_GAIN = 0.5 is the faster there; a loop that acts on measurements older than its last correction
should take 0.3.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError

DEFAULT_LOOP_GAIN = 0.5  # mu: the fraction of the estimated error corrected per update (see the module docstring)


@dataclass(frozen=True)
class SineControlLimits:
    """Tolerance bands (the loop has converged inside them) and abort limits (the vibration is ramped out
    beyond them), as a vibration test controller has. Amplitudes relative to the target; angles in deg."""

    tolerance_amplitude: float = 0.02
    tolerance_direction_deg: float = 0.5
    tolerance_off_axis: float = 0.01
    abort_amplitude_db: float = 3.0  # delivered this far above the target (20 log10 ratio): always judged
    abort_direction_deg: float = 10.0
    abort_off_axis: float = 0.25
    # the direction and off-axis limits hold from this many corrections on, or from the first update inside
    # every tolerance band if that comes first: uncorrected units (+-30 % gain, +-20 deg phase) tilt a
    # translation along the force line by up to ~30 deg, which the loop removes; once it has, a departure is
    # the plant's, not the loop's start
    converge_updates: int = 10
    # a loop that had to move the demands this far from where it started (the identification's feed-forward),
    # ||u - u0|| / ||u0||, says the identification no longer describes the robot: identify again
    stale_correction: float = 0.2
    # a unit whose delivered motion per demand (see unit_delivery) is further than this from 1 (complex: gain
    # and phase) is named in an abort's reason, whichever limit tripped first: it is the likely cause
    unit_delivery_band: float = 0.25


@dataclass(frozen=True)
class DeliveredSine:
    """How a measured response compares with the target: amplitude_ratio |along| / |target|;
    phase_error_rad of the along-axis motion against the target's; direction_error_deg of the in-phase
    motion line from the target axis; off_axis_ratio: the weighted norm of everything off the target axis
    (translation and rotation, in- and out of phase) per |along|."""

    amplitude_ratio: float
    phase_error_rad: float
    direction_error_deg: float
    off_axis_ratio: float

    @property
    def amplitude_error(self) -> float:
        """amplitude_ratio - 1 (0 on target)."""
        return self.amplitude_ratio - 1.0


@dataclass(frozen=True)
class ControlStep:
    """One update: the demand to send (6,) complex m; the figures of the measurement; verdict "converging",
    "in_tolerance" or "abort"; reason (why an abort, else "")."""

    demand: np.ndarray
    figures: DeliveredSine
    verdict: str
    reason: str = ""


def _weights(rotation_scale_m: float) -> np.ndarray:
    return np.array([1.0, 1.0, 1.0, rotation_scale_m, rotation_scale_m, rotation_scale_m])


def delivered_figures(measured, target, rotation_scale_m: float) -> DeliveredSine:
    """Compare a measured response (6,) complex with the target (6,) complex (see DeliveredSine)."""
    w = _weights(rotation_scale_m)
    m = np.asarray(measured, dtype=complex) * w
    t = np.asarray(target, dtype=complex) * w
    size = np.linalg.norm(t)
    if not np.isfinite(m).all() or size <= 0:
        raise InvalidInputError("delivered_figures needs a finite measurement and a non-zero target")
    axis = t / size  # complex: carries the target's phase
    along = np.vdot(axis, m)  # the measured amplitude along the target, relative phase
    off = m - along * axis
    in_phase_off = np.real(off * np.exp(-1j * np.angle(along))) if abs(along) > 0 else np.abs(off)
    magnitude = abs(along)
    return DeliveredSine(
        amplitude_ratio=float(magnitude / size),
        phase_error_rad=float(np.angle(along)),
        direction_error_deg=float(np.degrees(np.arctan2(np.linalg.norm(in_phase_off), magnitude))),
        off_axis_ratio=float(np.linalg.norm(off) / magnitude) if magnitude > 0 else float("inf"),
    )


def judge(figures: DeliveredSine, limits: SineControlLimits, updates: int | None = None) -> tuple[str, str]:
    """("abort", why) beyond an abort limit, ("in_tolerance", "") inside every band, else ("converging", "").
    ``updates``: the corrections made so far (None: judge every limit); the direction and off-axis limits
    hold from ``limits.converge_updates`` on, the amplitude limit always."""
    over_db = 20.0 * np.log10(max(figures.amplitude_ratio, 1e-300))
    if over_db > limits.abort_amplitude_db:
        return "abort", (f"delivered amplitude {figures.amplitude_ratio:.3f} x the target (+{over_db:.1f} dB, "
                         f"limit +{limits.abort_amplitude_db:g} dB)")
    converged = updates is None or updates >= limits.converge_updates
    if converged and figures.direction_error_deg > limits.abort_direction_deg:
        return "abort", (f"vibration direction {figures.direction_error_deg:.2f} deg off the target axis "
                         f"(limit {limits.abort_direction_deg:g} deg)")
    if converged and figures.off_axis_ratio > limits.abort_off_axis:
        return "abort", (f"off-axis motion {figures.off_axis_ratio:.1%} of the along-axis amplitude "
                         f"(limit {limits.abort_off_axis:.0%})")
    inside = (abs(figures.amplitude_error) <= limits.tolerance_amplitude
              and figures.direction_error_deg <= limits.tolerance_direction_deg
              and figures.off_axis_ratio <= limits.tolerance_off_axis)
    return ("in_tolerance" if inside else "converging"), ""


def unit_delivery(plant_estimate, measured, demand) -> np.ndarray:
    """Each unit's delivered motion per its demand, (6,) complex: the measured platform response (6,) complex
    mapped back to the legs through the plant estimate H (6, 6), H^-1 y / u; 1 for a unit that moves as it was
    identified to (a unit with no demand: 1)."""
    legs = np.linalg.solve(np.asarray(plant_estimate, dtype=complex), np.asarray(measured, dtype=complex))
    u = np.asarray(demand, dtype=complex)
    safe = np.abs(u) > 0
    return np.where(safe, legs / np.where(safe, u, 1.0), 1.0)


def unit_fault(delivery, band: float) -> str:
    """Which units deliver further than ``band`` from their demand (|r - 1| > band for a delivery r of
    unit_delivery), the worst first, with the gain and phase each delivers; "" when none does."""
    r = np.asarray(delivery, dtype=complex)
    off = np.abs(r - 1.0)
    faulty = [int(i) for i in np.argsort(-off) if off[i] > band]
    if not faulty:
        return ""
    # whole degrees as an int: a phase of -1e-14 deg (the solve's rounding) reads +0, never -0
    phases = [round(float(np.degrees(np.angle(r[i])))) for i in faulty]
    named = ", ".join(f"unit {i + 1} delivers {abs(r[i]):.2f} x its demand at {phase:+d} deg"
                      for i, phase in zip(faulty, phases, strict=True))
    return f"{named} (as identified: 1.00 x at +0 deg)"


class SineController:
    """The correction loop of one vibration (see the module docstring).

    Args:
        plant_estimate: H (6, 6) complex, platform response per leg demand.
        target: y* (6,) complex, the platform motion wanted at full amplitude.
        gain: mu in (0, 1], the fraction of the estimated error corrected per update (see the module docstring).
        rotation_scale_m: metres per radian when comparing rotations with translations.
        max_demand_m: (6,) or scalar, the largest demand amplitude a unit may be asked for (m).
        limits: tolerance bands and abort limits.
        initial_demand: u0 (6,) complex; default the feed-forward H^-1 y*.
    """

    def __init__(self, plant_estimate, target, gain: float = DEFAULT_LOOP_GAIN, rotation_scale_m: float = 0.1,
                 max_demand_m=np.inf, limits: SineControlLimits | None = None, initial_demand=None):
        self.estimate = np.asarray(plant_estimate, dtype=complex)
        self.target = np.asarray(target, dtype=complex)
        if self.estimate.shape != (6, 6) or self.target.shape != (6,) or not 0 < gain <= 1:
            raise InvalidInputError("SineController needs H (6, 6), a target (6,) and 0 < gain <= 1")
        if not (np.isfinite(self.estimate).all() and np.isfinite(self.target).all()):
            raise InvalidInputError("SineController: the plant estimate and the target must be finite")
        if np.linalg.cond(self.estimate) > 1e8:
            raise InvalidInputError("SineController: the plant estimate is singular")
        self.gain = float(gain)
        self.rotation_scale_m = float(rotation_scale_m)
        self.max_demand_m = np.broadcast_to(np.asarray(max_demand_m, dtype=float), (6,))
        self.limits = limits or SineControlLimits()
        self.demand = (np.linalg.solve(self.estimate, self.target) if initial_demand is None
                       else np.asarray(initial_demand, dtype=complex).reshape(6))
        self.initial = self.demand.copy()
        self.updates = 0
        self.settled = False  # an update was inside every tolerance band: every abort limit holds from then on

    @property
    def correction(self) -> float:
        """How far the loop moved the demands from where it started, ||u - u0|| / ||u0|| (0 before any
        correction): a large one says the plant is not the one its estimate was identified on."""
        scale = float(np.linalg.norm(self.initial))
        return float(np.linalg.norm(self.demand - self.initial)) / scale if scale > 0 else 0.0

    def with_unit_fault(self, reason: str, measured) -> str:
        """An abort's ``reason``, followed by the units that deliver off their demand in the response
        ``measured`` (6,) complex to the current demand at full amplitude (unit_fault), if any."""
        fault = unit_fault(unit_delivery(self.estimate, measured, self.demand), self.limits.unit_delivery_band)
        return f"{reason}; {fault}" if fault else reason

    def update(self, measured, envelope: float = 1.0) -> ControlStep:
        """Judge the response ``measured`` (6,) complex, taken while the vibration's envelope (its ramp) was
        ``envelope`` in (0, 1], and correct the demand at full amplitude only (a ramp's response is the
        ramp's, not the plant's steady state)."""
        if not 0 < envelope <= 1:
            raise InvalidInputError(f"envelope must be in (0, 1], got {envelope!r}")
        figures = delivered_figures(measured, self.target * envelope, self.rotation_scale_m)
        verdict, reason = judge(figures, self.limits, None if self.settled else self.updates)
        self.settled = self.settled or verdict == "in_tolerance"
        if verdict == "abort":
            reason = self.with_unit_fault(reason, np.asarray(measured) / envelope)  # as at full amplitude
            return ControlStep(self.demand.copy(), figures, verdict, reason)
        if envelope < 1.0:
            return ControlStep(self.demand.copy(), figures, verdict, reason)
        demand = self.demand + self.gain * np.linalg.solve(self.estimate, self.target - np.asarray(measured))
        over = np.abs(demand) > self.max_demand_m * (1 + 1e-9)
        if over.any():
            i = int(np.argmax(np.abs(demand) / self.max_demand_m))
            reason = (f"the correction asks unit {i + 1} for {abs(demand[i]) * 1e6:.1f} um, above its "
                      f"{self.max_demand_m[i] * 1e6:.1f} um (the plant is far from its identification)")
            return ControlStep(self.demand.copy(), figures, "abort", self.with_unit_fault(reason, measured))
        self.demand = demand
        self.updates += 1
        return ControlStep(demand.copy(), figures, verdict, reason)


def stale_identification(correction: float, limits: SineControlLimits) -> str:
    """Why the identification a vibration was planned with is stale, from its closed loop's ``correction``
    (``SineController.correction``); "" while it is not."""
    if correction > limits.stale_correction:
        return (f"the closed loop moved the legs' demands by {correction:.0%} of the identification's "
                f"feed-forward (more than {limits.stale_correction:.0%}): the identification no longer "
                "describes the robot")
    return ""


def iteration_spectral_radius(plant, estimate, gain: float, delay_updates: int = 0) -> float:
    """Spectral radius of the loop u_k+1 = u_k + gain H^-1 (y* - P u_k-d) around its fixed point, for the
    true plant ``plant`` P (6, 6), the estimate H (6, 6) and a delay of ``delay_updates`` d: below 1 the
    loop converges (geometrically, at that rate per update)."""
    p = np.asarray(plant, dtype=complex)
    h = np.asarray(estimate, dtype=complex)
    n = p.shape[0]
    step = gain * np.linalg.solve(h, p)  # H^-1 P
    d = int(delay_updates)
    # state [u_k, u_k-1, ..., u_k-d]
    a = np.zeros((n * (d + 1), n * (d + 1)), dtype=complex)
    a[:n, :n] = np.eye(n)
    a[:n, n * d:n * (d + 1)] -= step
    for k in range(d):
        a[n * (k + 1):n * (k + 2), n * k:n * (k + 1)] = np.eye(n)
    return float(np.max(np.abs(np.linalg.eigvals(a))))
