"""vibration.sine_control on a linear model of the robot (no MuJoCo): the platform's response is the kinematic
map J^-1 of the nominal robot times each unit's complex gain error; the loop corrects it from the measured
response. References: direct iteration of the linear model, and the closed-form stability of a scalar loop."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.errors import InvalidInputError
from stewart_vibration.kinematics.jacobian import jacobian
from stewart_vibration.paper import paper_pose
from stewart_vibration.vibration.sine_control import (
    SineController,
    SineControlLimits,
    delivered_figures,
    iteration_spectral_radius,
    judge,
    stale_identification,
    unit_delivery,
    unit_fault,
)

AMPLITUDE = 60e-6  # m: 0.3 g at 35 Hz
SCALE = 0.1  # m per rad


@pytest.fixture
def kinematic_map(robot):
    """J^-1 (6, 6) at the paper's pose: platform motion [dp; dphi] per leg length change."""
    return np.linalg.inv(jacobian(robot, paper_pose(robot)))


def target_along(direction, phase=0.0):
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    return AMPLITUDE * np.exp(1j * phase) * np.concatenate([d, np.zeros(3)])


def unit_errors(seed: int, gain=0.3, phase_deg=20.0):
    """Six complex unit gains within +-gain and +-phase_deg, the extremes included."""
    rng = np.random.default_rng(seed)
    g = 1 + rng.choice([-1, 1], 6) * rng.uniform(0.5, 1.0, 6) * gain
    p = np.radians(rng.choice([-1, 1], 6) * rng.uniform(0.5, 1.0, 6) * phase_deg)
    g[0], p[0] = 1 + gain, np.radians(phase_deg)
    g[1], p[1] = 1 - gain, -np.radians(phase_deg)
    return g * np.exp(1j * p)


@pytest.mark.parametrize("seed", range(10))
@pytest.mark.parametrize("delay", [0, 1])
def test_the_loop_converges_from_30_percent_gain_and_20_degree_phase_errors(kinematic_map, seed, delay):
    plant = kinematic_map @ np.diag(unit_errors(seed))
    target = target_along([0.3, -0.2, 0.93], phase=0.4)
    # the default gain (0.5) without delay; with one update of delay the gain the docstring gives for it
    loop = SineController(kinematic_map, target, rotation_scale_m=SCALE, **({} if delay == 0 else {"gain": 0.3}))
    open_loop = delivered_figures(plant @ loop.demand, target, SCALE)
    assert judge(open_loop, loop.limits, updates=0)[0] == "converging"  # visible, and no abort before correcting
    history = [loop.demand.copy()] * (delay + 1)
    verdicts = []
    for _ in range(100):
        step = loop.update(plant @ history[-1 - delay])
        assert step.verdict != "abort", step.reason
        history.append(step.demand)
        verdicts.append(step.verdict)
    assert verdicts[-1] == "in_tolerance" and verdicts.index("in_tolerance") < 30
    final = delivered_figures(plant @ loop.demand, target, SCALE)
    assert abs(final.amplitude_error) < 0.005 and final.direction_error_deg < 0.1 and final.off_axis_ratio < 0.005
    assert judge(final, loop.limits)[0] == "in_tolerance"


def test_the_error_shrinks_at_the_predicted_rate(kinematic_map):
    """Error per update from iterating the linear model equals the spectral radius of the loop."""
    plant = kinematic_map @ np.diag(unit_errors(4))
    target = target_along([0, 0, 1])
    loop = SineController(kinematic_map, target, gain=0.5, rotation_scale_m=SCALE)
    errors = []
    for _ in range(30):
        errors.append(np.linalg.norm(target - plant @ loop.demand))
        loop.update(plant @ loop.demand)
    rate = (errors[-1] / errors[-11]) ** 0.1
    assert abs(rate - iteration_spectral_radius(plant, kinematic_map, 0.5)) < 0.01


@pytest.mark.parametrize("delay, stable_ratio, unstable_ratio, stable_deg, unstable_deg",
                         [(0, 3.95, 4.05, 75.0, 76.0), (1, 1.95, 2.05, 46.0, 47.0)])
def test_the_documented_stability_margins(delay, stable_ratio, unstable_ratio, stable_deg, unstable_deg):
    """Scalar loop z^(d+1) - z^d + mu g = 0, mu = 0.5: d = 0 stable iff |1 - g / 2| < 1 (closed form);
    the margins the module states for d = 0 and d = 1."""
    eye = np.eye(6)

    def radius(g):
        return iteration_spectral_radius(g * eye, eye, 0.5, delay)

    assert radius(stable_ratio) < 1 < radius(unstable_ratio)
    assert radius(np.exp(1j * np.radians(stable_deg))) < 1 < radius(np.exp(1j * np.radians(unstable_deg)))
    if delay == 0:
        for g in (0.7 * np.exp(0.3j), 1.3 * np.exp(-0.35j), 3.0):
            assert abs(radius(g) - abs(1 - 0.5 * g)) < 1e-12


def test_delivered_figures_of_known_responses():
    target = target_along([0, 0, 1])
    tilted = AMPLITUDE * 1.1 * np.array([np.sin(np.radians(2.0)), 0, np.cos(np.radians(2.0)), 0, 0, 0])
    figures = delivered_figures(tilted, target, SCALE)
    assert abs(figures.direction_error_deg - 2.0) < 1e-9
    assert abs(figures.amplitude_ratio - 1.1 * np.cos(np.radians(2.0))) < 1e-12
    # an off-axis motion in quadrature (an ellipse) leaves the line's direction but is off-axis all the same
    ellipse = target + 1j * 0.05 * AMPLITUDE * np.array([1, 0, 0, 0, 0, 0])
    figures = delivered_figures(ellipse, target, SCALE)
    assert figures.direction_error_deg < 1e-9 and abs(figures.off_axis_ratio - 0.05) < 1e-12
    # a rotation counts by the scale: 1e-5 rad at 0.1 m/rad is 1 um
    rocking = target + np.array([0, 0, 0, 1e-5, 0, 0])
    assert abs(delivered_figures(rocking, target, SCALE).off_axis_ratio - 1e-6 / AMPLITUDE) < 1e-12
    assert abs(delivered_figures(target * np.exp(0.2j), target, SCALE).phase_error_rad - 0.2) < 1e-12


def test_each_abort_limit_and_the_demand_limit_end_the_loop_with_the_reason(kinematic_map):
    target = target_along([0, 0, 1])
    limits = SineControlLimits()
    loud = delivered_figures(target * 10 ** (3.1 / 20), target, SCALE)
    assert judge(loud, limits)[0] == "abort" and "+3.1 dB" in judge(loud, limits)[1]
    tilt = AMPLITUDE * np.array([np.sin(np.radians(12)), 0, np.cos(np.radians(12)), 0, 0, 0])
    assert judge(delivered_figures(tilt, target, SCALE), limits)[1].startswith("vibration direction 12.00 deg")
    wobble = target + 1j * 0.3 * AMPLITUDE * np.array([0, 1, 0, 0, 0, 0])
    assert "off-axis motion 30.0%" in judge(delivered_figures(wobble, target, SCALE), limits)[1]
    # a unit that fails to half its gain asks the loop for more than a unit can give
    loop = SineController(kinematic_map, target, max_demand_m=1.2 * np.abs(np.linalg.solve(kinematic_map, target)))
    plant = kinematic_map @ np.diag([0.5, 1, 1, 1, 1, 1])
    verdicts = [loop.update(plant @ loop.demand) for _ in range(20)]
    aborts = [v for v in verdicts if v.verdict == "abort"]
    assert aborts and "unit 1" in aborts[0].reason and "above its" in aborts[0].reason
    assert "; unit 1 delivers 0.50 x its demand at +0 deg" in aborts[0].reason
    # the demand stays what it was when the loop refused to go on
    assert np.all(np.abs(aborts[0].demand) <= loop.max_demand_m * (1 + 1e-9))


def test_a_ramp_is_judged_but_not_corrected_and_bad_set_ups_are_refused(kinematic_map):
    target = target_along([0, 0, 1])
    loop = SineController(kinematic_map, target)
    before = loop.demand.copy()
    step = loop.update(0.5 * kinematic_map @ before * 0.9, envelope=0.5)
    assert step.verdict == "converging" and np.array_equal(loop.demand, before) and loop.updates == 0
    with pytest.raises(InvalidInputError):
        SineController(np.zeros((6, 6)), target)
    with pytest.raises(InvalidInputError):
        SineController(kinematic_map, target, gain=1.5)
    with pytest.raises(InvalidInputError):
        loop.update(target, envelope=0.0)


@pytest.mark.parametrize("gain, delay, worst", [(0.5, 0, 0.682), (0.3, 0, 0.806), (0.5, 1, 0.923), (0.3, 1, 0.778)])
def test_the_documented_worst_rates_over_the_unit_error_box(gain, delay, worst):
    """The module's worst convergence rates over +-30 % gain and +-20 deg phase, on a grid of that box."""
    rates = [iteration_spectral_radius(np.array([[g * np.exp(1j * np.radians(p))]]), np.eye(1), gain, delay)
             for g in np.linspace(0.7, 1.3, 13) for p in np.linspace(-20, 20, 9)]
    assert abs(max(rates) - worst) < 0.001


def test_the_correction_is_how_far_the_loop_moved_the_demands_and_a_large_one_is_stale(kinematic_map):
    """One update on a plant whose unit 1 has half the estimate's gain: u1 = u0 + mu H^-1 (y* - H D u0)
    = u0 + mu (1 - 0.5) u0[0] e1, so the correction ||u1 - u0|| / ||u0|| is 0.25 |u0[0]| / ||u0|| (mu 0.5)."""
    loop = SineController(kinematic_map, target_along([0, 0, 1]), gain=0.5)
    u0 = loop.demand.copy()
    assert loop.correction == 0.0
    loop.update(kinematic_map @ np.diag([0.5, 1, 1, 1, 1, 1]) @ u0)
    assert abs(loop.correction - 0.25 * abs(u0[0]) / np.linalg.norm(u0)) < 1e-12
    limits = SineControlLimits()
    assert stale_identification(0.2, limits) == ""
    assert stale_identification(0.21, limits).startswith("the closed loop moved the legs' demands by 21% ")


def test_the_unit_that_delivers_off_its_demand_is_named_whichever_limit_trips(kinematic_map):
    """A plant whose unit 3 moves 0.6 x at +20 deg and unit 5 1.4 x its demand: H^-1 (H D u) / u is D's
    diagonal, so the diagnosis reads those gains back; a healthy plant names no unit."""
    target = target_along([0, 0, 1])
    faults = np.ones(6, complex)
    faults[2], faults[4] = 0.6 * np.exp(1j * np.radians(20)), 1.4
    loop = SineController(kinematic_map, target)
    measured = kinematic_map @ (faults * loop.demand)
    assert np.allclose(unit_delivery(kinematic_map, measured, loop.demand), faults, atol=1e-9)
    band = SineControlLimits().unit_delivery_band
    fault = unit_fault(unit_delivery(kinematic_map, measured, loop.demand), band)
    # the worst first: |0.6 e^(20j deg) - 1| = 0.48 > |1.4 - 1|
    assert fault == ("unit 3 delivers 0.60 x its demand at +20 deg, unit 5 delivers 1.40 x its demand at +0 deg "
                     "(as identified: 1.00 x at +0 deg)"), fault
    assert unit_fault(unit_delivery(kinematic_map, kinematic_map @ loop.demand, loop.demand), band) == ""
    # just inside the band: not named
    assert unit_fault(np.array([1.24, 1, 1, 1, 1, 1]), 0.25) == ""
    # a phase a rounding below zero reads +0 (the solve's noise differs between BLAS builds and thread counts)
    assert unit_fault(np.array([1.4 * np.exp(-1e-16j), 1, 1, 1, 1, 1]), 0.25).startswith(
        "unit 1 delivers 1.40 x its demand at +0 deg")
    # the direction limit trips (judged on every limit) and the abort names the units behind it
    ten_corrections = SineController(kinematic_map, target, limits=SineControlLimits(converge_updates=0))
    step = ten_corrections.update(kinematic_map @ (faults * ten_corrections.demand))
    assert step.verdict == "abort" and step.reason.startswith(("vibration direction", "off-axis motion"))
    assert "unit 5 delivers 1.40 x" in step.reason and "unit 3 delivers 0.60 x" in step.reason
    # a ramp's response is read at full amplitude: half the envelope, half the response, the same diagnosis
    ramping = SineController(kinematic_map, target, limits=SineControlLimits(converge_updates=0))
    step = ramping.update(0.5 * kinematic_map @ (faults * ramping.demand), envelope=0.5)
    assert step.verdict == "abort" and "unit 3 delivers 0.60 x its demand at +20 deg" in step.reason


def test_once_inside_the_bands_every_abort_limit_holds_at_once(kinematic_map):
    """Before convergence the direction limit waits for converge_updates corrections (the loop removes the
    units' initial tilt); once an update was inside every band, a 12 deg tilt from a changed plant aborts at
    the next update, however few corrections were made."""
    target = target_along([0, 0, 1])
    tilt = AMPLITUDE * np.array([np.sin(np.radians(12)), 0, np.cos(np.radians(12)), 0, 0, 0])
    fresh = SineController(kinematic_map, target)
    assert fresh.update(tilt).verdict == "converging" and fresh.updates == 1  # not judged on direction yet
    settled = SineController(kinematic_map, target)
    assert settled.update(target).verdict == "in_tolerance" and settled.updates == 1
    step = settled.update(tilt)
    assert step.verdict == "abort" and step.reason.startswith("vibration direction 12.00 deg"), step.reason
