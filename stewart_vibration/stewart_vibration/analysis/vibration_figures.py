"""The figures of one vibration step of a suite run, measured against what was planned (pure: no rclpy).

The ground-truth platform vibration (direction and amplitude error against the decomposition at the nominal
pose; base frame), each leg's measured vibration (actual hinge length leg_i + vib_i: amplitude against |k_i| A,
phase against 0/pi, frequency), the active duration, the leg-force model error (legs/force_estimate against the
emulator's measured efforts) and the same platform and leg figures in the controller's view. Lengths in m,
angles in deg, times in sim s, frequencies in Hz.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kinematics.rotations import wrap_angle
from ..robot import Robot
from ..vibration.decompose import VibrationDecomposition
from ..vibration.settings import VIBRATION_KEYS, plan_vibration
from ..vibration.sine_fit import SineSums, SinusoidFit
from .fits import (
    direction_error_deg,
    fit_sinusoid,
    force_error,
    leg_phase_offsets_deg,
    line_of_fit,
    phase_error_to_0_or_pi_deg,
    phase_offsets_deg,
)
from .report_scan import ForceErrorScan
from .tissue_figures import tissue_leg_forces

STEADY_MARGIN_S = 0.2  # skip this much after the ramp-in and before the ramp-out


def period_peaks(times, vib, frequency: float, start: float, end: float) -> tuple[np.ndarray, int]:
    """(the peak |vib_i| [bins, 6] (m) over each period-long bin of [start, end] (s), 0 in a bin without samples;
    the samples in [start, end]). Peaks of parts of a run combine by their maximum."""
    sel = (times >= start) & (times <= end)
    t, v = times[sel], np.abs(vib[sel])
    period = 1.0 / frequency
    peaks = np.zeros((int(np.floor((end - start) / period)) + 1, np.shape(vib)[1]))
    np.maximum.at(peaks, np.floor((t - start) / period).astype(int), v)
    return peaks, int(t.size)


def active_time(peaks: np.ndarray, leg_amplitudes, frequency: float) -> float:
    """The active time (s, a whole number of periods) of period peaks [bins, 6] (``period_peaks``): the bins where
    every leg planned at more than 20 % of the largest amplitude |k_i| A (``leg_amplitudes`` [6], m) reaches half
    its planned amplitude, a period each (the planned active time of a ramped vibration is duration - ramp)."""
    leg_amplitudes = np.asarray(leg_amplitudes, float)
    strong = leg_amplitudes > 0.2 * leg_amplitudes.max()
    half = (peaks[:, strong] >= 0.5 * leg_amplitudes[strong]).all(axis=1)
    return float(half.sum() * (1.0 / frequency))


def vibration_start(signals: dict, after: float) -> float:
    """The vibration's common start time t0 (sim s): a window stamped ``after`` exactly (the plan's t0: an
    identification's windows on the same topic, stamped just before, do not count), else the first vib window
    stamp from ``after`` - 1 s on.

    Args:
        signals: from ``load_signals`` (vibration_starts, s).
        after: a lower bound of t0 (sim s).

    Returns:
        t0 (sim s).

    Raises:
        ValueError: no vibration/joint_trajectory window is stamped at or after ``after`` - 1 s.
    """
    starts = signals["vibration_starts"]
    exact = starts[np.abs(starts - after) < 1e-6]  # ``after`` is t0 itself (the plan's): no other window counts
    if exact.size:
        return float(exact[0])
    later = starts[starts >= after - 1.0]  # the caller's clock may run ahead of the planner's
    if later.size == 0:
        raise ValueError(f"no vibration/joint_trajectory window stamped after {after:.3f} s in the run")
    return float(later[0])


def steady_window(start: float, duration: float, ramp: float) -> tuple[float, float]:
    """(t0, t1) (s) of a vibration's steady part: after the ramp-in and before the ramp-out, with
    STEADY_MARGIN_S more on both sides.

    Args:
        start: the vibration's start t0 (s).
        duration: the vibration's duration including both ramps (s).
        ramp: the ramp time (s).

    Returns:
        (start + ramp + STEADY_MARGIN_S, start + duration - ramp - STEADY_MARGIN_S) (s).
    """
    return start + ramp + STEADY_MARGIN_S, start + duration - ramp - STEADY_MARGIN_S


def platform_vibration(signals: dict, t0: float, t1: float, frequency: float, streamed: SineSums | None = None) -> dict:
    """The platform's vibration over [t0, t1] (s) from the ground-truth poses: the fundamental at
    ``frequency`` (Hz) fitted to the positions (``fits.line_vibration``), with the sums of the poses of the
    window not held (``streamed``, see ``window_fit``). The one computation of "platform amplitude" (run summary
    and run report).

    Returns:
        {direction (3,) unit, base frame; amplitude_m; off_axis_ratio; samples}.
    """
    pt, poses = signals["pose"]
    sel = (pt >= t0) & (pt <= t1)
    samples = int(sel.sum()) + (streamed.count if streamed is not None else 0)
    if samples < 4:  # it never ran (refused, aborted, interrupted) or the log lacks the ground truth
        raise ValueError(f"only {samples} ground-truth poses in its steady part {t0:.3f}..{t1:.3f} s (it did "
                         "not run, or the log holds no ground_truth/platform_pose for it)")
    line = line_of_fit(window_fit(pt, poses[:, :3], sel, frequency, (t0, t1), streamed))
    return {"direction": line.direction, "amplitude_m": line.amplitude, "off_axis_ratio": line.off_axis_ratio,
            "samples": samples}


def window_fit(times, values, selected, frequency: float, window: tuple[float, float],
               streamed: SineSums | None = None) -> SinusoidFit:
    """``fit_sinusoid`` at ``frequency`` of the ``selected`` rows of values [n, k] (times [n] s), together with
    the samples of the same window that were summed as they streamed past instead of held (``streamed``: its
    SineSums over ``window``); without streamed samples fit_sinusoid itself."""
    if streamed is None or not (streamed.count or streamed.not_finite):
        return fit_sinusoid(times[selected], values[selected], frequency)
    held = SineSums(frequency, np.shape(values)[1], window)
    held.add(times[selected], values[selected])
    return held.merged(streamed).fit()


def leg_force_error(robot: Robot, signals: dict, t0: float, t1: float, frequency: float | None,
                    streamed: ForceErrorScan | None = None) -> dict | None:
    """The leg-force model (legs/force_estimate) against the emulator's measured efforts over [t0, t1] (s),
    minus the forces of the applied tissue wrench (the environment, not part of the model:
    ``tissue_leg_forces``). The one computation of "force error" (``fits.force_error``: RMS on the measured
    stamps, relative to the fitted force amplitude at ``frequency``, or half the peak-to-peak without one).
    ``streamed``: the same over the window's samples that were not held (a run without tissue), each part's
    measured samples against that part's estimates.

    Returns:
        force_error's dict, or None with fewer than four estimates in the window.
    """
    jt, joints = signals["joints"]
    ft, forces = signals["force_estimate"]
    sel, fsel = (jt >= t0) & (jt <= t1), (ft >= t0) & (ft <= t1)
    if streamed is not None and streamed.estimates:
        held = ForceErrorScan(frequency=frequency, window=(t0, t1))
        held.add_estimates(ft[fsel], forces["effort"][fsel])
        held.add_measured(jt[sel], joints["effort"][sel, :6])
        return held.combined(streamed)
    if fsel.sum() < 4:
        return None
    measured = joints["effort"][sel, :6] - tissue_leg_forces(robot, signals, jt[sel])
    return force_error(ft[fsel], forces["effort"][fsel], jt[sel], measured, frequency)


def summarize_vibration(robot: Robot, signals: dict, nominal_pose, settings: dict, start_time: float,
                        streamed=None) -> dict:
    """Measured vs planned for one vibration step.

    Args:
        robot: the robot.
        signals: from ``load_signals`` (or the planning UI's live buffers in the same form).
        nominal_pose: the platform pose [6] the vibration was planned at (m, rad).
        settings: the settings of the vibration that ran (the vibrate goal's: every key of
            ``vibration.settings.VIBRATION_KEYS``; no defaults are filled in here).
        start_time: a lower bound of the vibration's t0 (sim s; every window is stamped with t0).
        streamed: a long vibration's middle, not in ``signals`` but summed as it streamed past
            (``vibration_scan.SteadyStream``); None: every sample is in ``signals``.

    Returns:
        The figures of the vibration (see ``check_bounds`` for the ones judged).

    Raises:
        KeyError: a setting is missing; ValueError: no window of the vibration was recorded.
    """
    frame = streamed.frame if streamed is not None else vibration_frame(robot, signals, nominal_pose, settings,
                                                                        start_time)
    plan, frequency, start, (t0, t1) = frame.plan, frame.frequency, frame.start, frame.window
    out = {"frequency_hz": frequency, "planned_amplitude_m": plan.amplitude, "planned_direction": plan.direction,
           "start_time_s": start, "window_s": [t0, t1], "gains": plan.gains}
    line = platform_vibration(signals, t0, t1, frequency, streamed.pose if streamed else None)
    out.update({
        "measured_direction": line["direction"],
        "direction_error_deg": direction_error_deg(line["direction"], plan.direction),
        "measured_amplitude_m": line["amplitude_m"],
        "amplitude_error": abs(line["amplitude_m"] / plan.amplitude - 1.0),
        "off_axis_ratio": line["off_axis_ratio"],
        "window_samples": line["samples"],
    })
    jt, joints = signals["joints"]
    sel = (jt >= t0) & (jt <= t1)
    hinge = joints["position"][:, :6] + joints["position"][:, 6:12]
    middle = 0.5 * (t0 + t1)
    fit = window_fit(jt, hinge, sel, frequency, (t0, t1), streamed.hinge if streamed else None)
    first = window_fit(jt, hinge, sel & (jt < middle), frequency, (t0, t1), streamed.first if streamed else None)
    second = window_fit(jt, hinge, sel & (jt >= middle), frequency, (t0, t1), streamed.second if streamed else None)
    offsets = leg_phase_offsets_deg(fit)
    dt_halves = 0.5 * (t1 - t0)
    leg_freq = frequency + wrap_angle(second.phase - first.phase) / (2 * np.pi * dt_halves)
    expected_offsets = phase_offsets_deg(plan.leg_phases, int(np.argmax(fit.amplitude)))
    out.update({
        "leg_amplitude_m": fit.amplitude,
        "leg_amplitude_expected_m": plan.leg_amplitudes,
        "leg_amplitude_error": np.abs(fit.amplitude / plan.leg_amplitudes - 1.0),
        "leg_phase_deg": offsets,
        "leg_phase_expected_deg": expected_offsets,
        "leg_phase_error_deg": phase_error_to_0_or_pi_deg(offsets),
        "leg_phase_sign_ok": bool(np.all(np.abs(wrap_angle(np.radians(offsets - expected_offsets)))
                                         < np.radians(90))),
        "leg_frequency_hz": leg_freq,
        "leg_frequency_spread_hz": float(np.ptp(leg_freq)),
        "leg_frequency_error_hz": float(np.abs(leg_freq - frequency).max()),
    })
    planned_active = frame.duration - frame.ramp
    peaks, samples = period_peaks(jt, joints["position"][:, 6:12], frequency, start, frame.activity_end)
    if streamed is not None:
        peaks, samples = np.maximum(peaks, streamed.peaks), samples + streamed.peak_samples
    measured_active = active_time(peaks, plan.leg_amplitudes, frequency) if samples >= 2 else 0.0
    out.update({"active_duration_s": measured_active, "planned_active_duration_s": planned_active,
                "active_duration_error_s": abs(measured_active - planned_active)})
    out["force"] = leg_force_error(robot, signals, t0, t1, frequency, streamed.force if streamed else None)
    out["controller_view"] = controller_view(signals, t0, t1, frequency, plan, streamed)
    return out


@dataclass(frozen=True)
class VibrationFrame:
    """Where a vibration step's figures are read: its plan at the nominal pose, its frequency (Hz), ramp and
    duration (s, both ramps included), its start t0, steady window (t0, t1) and the end of the span its active
    time is counted over (sim s)."""

    plan: VibrationDecomposition
    frequency: float
    ramp: float
    duration: float
    start: float
    window: tuple[float, float]
    activity_end: float


def vibration_frame(robot: Robot, signals: dict, nominal_pose, settings: dict, start_time: float) -> VibrationFrame:
    """The VibrationFrame of a vibration step (arguments as ``summarize_vibration``'s): its start from the
    recorded windows (``vibration_start``), its steady window (``steady_window``).

    Raises:
        KeyError: a setting is missing; ValueError: no window of the vibration was recorded.
    """
    s = {key: settings[key] for key in VIBRATION_KEYS}
    frequency, ramp, duration = float(s["frequency_hz"]), float(s["ramp_s"]), float(s["duration_s"])
    plan = plan_vibration(robot, nominal_pose, s, check_limits=False, method="linear")
    start = vibration_start(signals, start_time)
    return VibrationFrame(plan=plan, frequency=frequency, ramp=ramp, duration=duration, start=start,
                          window=steady_window(start, duration, ramp), activity_end=start + duration + 1.0)


def controller_view(signals: dict, t0: float, t1: float, frequency: float, plan, streamed=None) -> dict | None:
    """The vibration as the controller sees it over [t0, t1] (s): the platform line fitted to its pose estimate
    (platform/pose_estimate) and the leg amplitudes its sensors read (legs/joint_states: encoder + unit
    sensor), against the plan; with ``streamed`` (as ``summarize_vibration``'s) the window's samples not held
    too. None when the log holds fewer than four estimates in the window.

    Returns:
        {direction_error_deg, amplitude_error, off_axis_ratio, measured_amplitude_m, leg_amplitude_error (6,)}.
    """
    estimate = signals.get("pose_estimate")
    extra = streamed.estimate if streamed is not None else None
    held = int(((estimate[0] >= t0) & (estimate[0] <= t1)).sum()) if estimate is not None else 0
    if estimate is None or held + (extra.count if extra is not None else 0) < 4:
        return None
    line = platform_vibration({"pose": estimate}, t0, t1, frequency, extra)
    out = {"direction_error_deg": direction_error_deg(line["direction"], plan.direction),
           "amplitude_error": abs(line["amplitude_m"] / plan.amplitude - 1.0),
           "off_axis_ratio": line["off_axis_ratio"], "measured_amplitude_m": line["amplitude_m"]}
    jt, joints = signals.get("sensed_joints", signals["joints"])
    sel = (jt >= t0) & (jt <= t1)
    sensed = streamed.sensed if streamed is not None else None
    if sel.sum() + (sensed.count if sensed is not None else 0) >= 4:
        fit = window_fit(jt, joints["position"][:, :6] + joints["position"][:, 6:12], sel, frequency, (t0, t1),
                         sensed)
        out["leg_amplitude_error"] = np.abs(fit.amplitude / plan.leg_amplitudes - 1.0)
    return out
