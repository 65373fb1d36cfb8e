"""The figures of one vibration step of a suite run, measured against what was planned (pure: no rclpy).

The ground-truth platform vibration (direction and amplitude error against the decomposition at the nominal
pose; base frame), each leg's measured vibration (actual hinge length leg_i + vib_i: amplitude against |k_i| A,
phase against 0/pi, frequency), the active duration, the leg-force model error (legs/force_estimate against the
emulator's measured efforts) and the same platform and leg figures in the controller's view. Lengths in m,
angles in deg, times in sim s, frequencies in Hz.
"""

from __future__ import annotations

import numpy as np

from ..kinematics.rotations import wrap_angle
from ..robot import Robot
from ..vibration.settings import VIBRATION_KEYS, plan_vibration
from .fits import (
    direction_error_deg,
    fit_sinusoid,
    force_error,
    leg_phase_offsets_deg,
    line_vibration,
    phase_error_to_0_or_pi_deg,
    phase_offsets_deg,
)
from .tissue_figures import tissue_leg_forces

STEADY_MARGIN_S = 0.2  # skip this much after the ramp-in and before the ramp-out


def active_duration(times, vib, leg_amplitudes, frequency: float, start: float, end: float) -> float:
    """Time (s) within [start, end] during which the vibration units moved at >= half their planned
    amplitude: the peak |vib_i| over each period-long bin, against 0.5 |k_i| A (the planned active time of
    a ramped vibration is duration - ramp).

    Only legs planned at more than 20 % of the largest amplitude count; all of them must reach half.

    Args:
        times: sample times [n] (s).
        vib: vib_* displacements [n, 6] (m).
        leg_amplitudes: planned leg amplitudes |k_i| A [6] (m).
        frequency: the vibration frequency (Hz).
        start: start of the interval (s).
        end: end of the interval (s).

    Returns:
        The active time (s, a whole number of periods); 0.0 with fewer than 2 samples in [start, end].
    """
    sel = (times >= start) & (times <= end)
    t, v = times[sel], np.abs(vib[sel])
    if t.size < 2:
        return 0.0
    period = 1.0 / frequency
    bins = np.floor((t - start) / period).astype(int)
    peaks = np.zeros((bins.max() + 1, v.shape[1]))
    np.maximum.at(peaks, bins, v)
    strong = leg_amplitudes > 0.2 * leg_amplitudes.max()
    half = (peaks[:, strong] >= 0.5 * leg_amplitudes[strong]).all(axis=1)
    return float(half.sum() * period)


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


def platform_vibration(signals: dict, t0: float, t1: float, frequency: float) -> dict:
    """The platform's vibration over [t0, t1] (s) from the ground-truth poses: the fundamental at
    ``frequency`` (Hz) fitted to the positions (``fits.line_vibration``). The one computation of "platform
    amplitude" (run summary and run report).

    Returns:
        {direction (3,) unit, base frame; amplitude_m; off_axis_ratio; samples}.
    """
    pt, poses = signals["pose"]
    sel = (pt >= t0) & (pt <= t1)
    if sel.sum() < 4:  # it never ran (refused, aborted, interrupted) or the log lacks the ground truth
        raise ValueError(f"only {int(sel.sum())} ground-truth poses in its steady part {t0:.3f}..{t1:.3f} s (it did "
                         "not run, or the log holds no ground_truth/platform_pose for it)")
    line = line_vibration(pt[sel], poses[sel, :3], frequency)
    return {"direction": line.direction, "amplitude_m": line.amplitude, "off_axis_ratio": line.off_axis_ratio,
            "samples": int(sel.sum())}


def leg_force_error(robot: Robot, signals: dict, t0: float, t1: float, frequency: float | None) -> dict | None:
    """The leg-force model (legs/force_estimate) against the emulator's measured efforts over [t0, t1] (s),
    minus the forces of the applied tissue wrench (the environment, not part of the model:
    ``tissue_leg_forces``). The one computation of "force error" (``fits.force_error``: RMS on the measured
    stamps, relative to the fitted force amplitude at ``frequency``, or half the peak-to-peak without one).

    Returns:
        force_error's dict, or None with fewer than four estimates in the window.
    """
    jt, joints = signals["joints"]
    ft, forces = signals["force_estimate"]
    sel, fsel = (jt >= t0) & (jt <= t1), (ft >= t0) & (ft <= t1)
    if fsel.sum() < 4:
        return None
    measured = joints["effort"][sel, :6] - tissue_leg_forces(robot, signals, jt[sel])
    return force_error(ft[fsel], forces["effort"][fsel], jt[sel], measured, frequency)


def summarize_vibration(robot: Robot, signals: dict, nominal_pose, settings: dict, start_time: float) -> dict:
    """Measured vs planned for one vibration step.

    Args:
        robot: the robot.
        signals: from ``load_signals`` (or the planning UI's live buffers in the same form).
        nominal_pose: the platform pose [6] the vibration was planned at (m, rad).
        settings: the settings of the vibration that ran (the vibrate goal's: every key of
            ``vibration.settings.VIBRATION_KEYS``; no defaults are filled in here).
        start_time: a lower bound of the vibration's t0 (sim s; every window is stamped with t0).

    Returns:
        The figures of the vibration (see ``check_bounds`` for the ones judged).

    Raises:
        KeyError: a setting is missing; ValueError: no window of the vibration was recorded.
    """
    s = {key: settings[key] for key in VIBRATION_KEYS}
    frequency, ramp, duration = float(s["frequency_hz"]), float(s["ramp_s"]), float(s["duration_s"])
    plan = plan_vibration(robot, nominal_pose, s, check_limits=False, method="linear")
    start = vibration_start(signals, start_time)
    t0, t1 = steady_window(start, duration, ramp)
    out = {"frequency_hz": frequency, "planned_amplitude_m": plan.amplitude, "planned_direction": plan.direction,
           "start_time_s": start, "window_s": [t0, t1], "gains": plan.gains}
    line = platform_vibration(signals, t0, t1, frequency)
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
    hinge = joints["position"][sel, :6] + joints["position"][sel, 6:12]
    fit = fit_sinusoid(jt[sel], hinge, frequency)
    offsets = leg_phase_offsets_deg(fit)
    half = jt[sel] < 0.5 * (t0 + t1)
    first, second = fit_sinusoid(jt[sel][half], hinge[half], frequency), fit_sinusoid(jt[sel][~half], hinge[~half],
                                                                                      frequency)
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
    planned_active = duration - ramp
    measured_active = active_duration(jt, joints["position"][:, 6:12], plan.leg_amplitudes, frequency, start,
                                      start + duration + 1.0)
    out.update({"active_duration_s": measured_active, "planned_active_duration_s": planned_active,
                "active_duration_error_s": abs(measured_active - planned_active)})
    out["force"] = leg_force_error(robot, signals, t0, t1, frequency)
    out["controller_view"] = controller_view(signals, t0, t1, frequency, plan)
    return out


def controller_view(signals: dict, t0: float, t1: float, frequency: float, plan) -> dict | None:
    """The vibration as the controller sees it over [t0, t1] (s): the platform line fitted to its pose estimate
    (platform/pose_estimate) and the leg amplitudes its sensors read (legs/joint_states: encoder + unit
    sensor), against the plan. None when the log holds fewer than four estimates in the window.

    Returns:
        {direction_error_deg, amplitude_error, off_axis_ratio, measured_amplitude_m, leg_amplitude_error (6,)}.
    """
    estimate = signals.get("pose_estimate")
    if estimate is None or int(((estimate[0] >= t0) & (estimate[0] <= t1)).sum()) < 4:
        return None
    line = platform_vibration({"pose": estimate}, t0, t1, frequency)
    out = {"direction_error_deg": direction_error_deg(line["direction"], plan.direction),
           "amplitude_error": abs(line["amplitude_m"] / plan.amplitude - 1.0),
           "off_axis_ratio": line["off_axis_ratio"], "measured_amplitude_m": line["amplitude_m"]}
    jt, joints = signals.get("sensed_joints", signals["joints"])
    sel = (jt >= t0) & (jt <= t1)
    if sel.sum() >= 4:
        fit = fit_sinusoid(jt[sel], joints["position"][sel, :6] + joints["position"][sel, 6:12], frequency)
        out["leg_amplitude_error"] = np.abs(fit.amplitude / plan.leg_amplitudes - 1.0)
    return out
