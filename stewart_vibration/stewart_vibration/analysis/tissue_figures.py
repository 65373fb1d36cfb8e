"""The soft-tissue figures of a suite run (pure: no rclpy).

The external-wrench estimate against the wrench the emulator applied (ground_truth/tissue_wrench), in moves and
holds and during vibrations, every force-guard trip (kinematics/guard_status) with the peak load it let through,
and the axial leg forces (N) the applied wrench puts on the legs. Forces in N, moments in N m, times in sim s.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..dynamics.newton_euler import leg_forces
from ..errors import MalformedMessageError
from ..messages.status_values import guard_status_from_cdr
from ..motion.guard_status import GuardStatus
from ..robot import Robot


def tissue_leg_forces(robot: Robot, signals: dict, times) -> np.ndarray | float:
    """The axial forces [n, 6] (N) the applied tissue wrench (ground_truth/tissue_wrench, ground truth) puts on the
    legs at the states ``times`` [n] (s), at the ground-truth poses; 0 without tissue. The leg-force figure
    compares the robot's model (legs/force_estimate: no external load) with the measured efforts minus this:
    the tissue is the environment, not part of the model the figure checks.

    Args:
        robot: the robot.
        signals: from ``load_signals`` (tissue_wrench, pose).
        times: state times [n] (s); wrench and pose are linearly interpolated to them.

    Returns:
        Leg forces [n, 6] (N), or 0.0 without a recorded tissue wrench.

    Raises:
        ValueError: a tissue wrench but no ground-truth pose is recorded (``np.interp``).
        numpy.linalg.LinAlgError: the leg-force system is singular at a sample (``leg_forces``).
    """
    ta, wrench = signals.get("tissue_wrench", (np.empty(0), None))
    if not ta.size:
        return 0.0
    pt, poses = signals["pose"]
    times = np.asarray(times, float)
    w = np.stack([np.interp(times, ta, wrench[:, k]) for k in range(6)], axis=1)
    pose = np.stack([np.interp(times, pt, poses[:, k]) for k in range(6)], axis=1)
    zero = np.zeros_like(pose)
    return leg_forces(robot, pose, zero, zero, external_wrench=w) - leg_forces(robot, pose, zero, zero)


def guard_trips(signals: dict) -> list[GuardStatus]:
    """Every force-guard trip in kinematics/guard_status (the last status of each trip: its final peaks).

    Args:
        signals: from ``load_signals`` (guard_status: the raw ForceGuardStatus messages).

    Returns:
        One motion.guard_status.GuardStatus per trip, in order of trip_time_s. A status that cannot be read (a
        spoofed one, say) is left out.
    """
    trips: dict[float, GuardStatus] = {}
    for data in signals.get("guard_status", []):
        try:
            status = guard_status_from_cdr(data)
        except MalformedMessageError:
            continue
        if status.tripped:
            trips[status.trip_time_s] = status
    return [trips[k] for k in sorted(trips)]


def summarize_tissue(signals: dict, vibrations=(), moment_scale_m: float = 0.1) -> dict | None:
    """External-wrench estimate vs the applied tissue wrench (None without ground_truth/tissue_wrench).

    vibrations: (t0, duration) (s) of each vibration; its states count as "vibration", every other state
    of the run as "moves and holds". Errors: RMS over the states of |estimate - applied| of the force (N) and
    of the moment (N m); relative = RMS / the run's peak applied magnitude. A run whose peak moment is below
    1 % of the peak force x ``moment_scale_m`` (e.g. a pure distraction along the tibia axis: ~1e-11 N m)
    has no relative moment error (None): its absolute error is reported. Guard trips: the peak estimated
    and applied force from the trip to the end of its stop (+ 0.5 s) against guard_force_n.

    Args:
        signals: from ``load_signals`` (tissue_wrench, wrench_estimate, guard_status).
        vibrations: (t0, duration) (s) of each vibration.
        moment_scale_m: length (m) that scales the peak force to the smallest peak moment judged.

    Returns:
        None without applied or estimated wrenches; else {"samples", "peak_force_n", "peak_moment_nm",
        "moves_holds": {"samples", "rms_force_error_n", "rms_moment_error_nm", "relative_force",
        "relative_moment" (or None)}, "vibration": the same RMS errors or None, "guard": one dict per trip}.

    Raises:
        ValueError: no applied and estimated wrench share a stamp (an empty maximum), or a trip's
            status value is not a number.
    """
    ta, applied = signals["tissue_wrench"]
    te, estimate = signals["wrench_estimate"]
    if not ta.size or not te.size:
        return None
    common, ia, ie = np.intersect1d(np.round(ta, 6), np.round(te, 6), return_indices=True)
    applied, estimate, t = applied[ia], estimate[ie], common
    err = estimate - applied
    in_vib = np.zeros(t.size, dtype=bool)
    for t0, duration in vibrations:
        in_vib |= (t >= t0) & (t <= t0 + duration)
    peak_f = float(np.linalg.norm(applied[:, :3], axis=1).max())
    peak_m = float(np.linalg.norm(applied[:, 3:], axis=1).max())

    def rms(rows, part):
        return float(np.sqrt((np.linalg.norm(rows[:, part], axis=1) ** 2).mean())) if len(rows) else float("nan")

    quiet = err[~in_vib]
    out: dict[str, Any] = {
        "samples": int(t.size), "peak_force_n": peak_f, "peak_moment_nm": peak_m,
        "moves_holds": {"samples": int(len(quiet)), "rms_force_error_n": rms(quiet, slice(0, 3)),
                        "rms_moment_error_nm": rms(quiet, slice(3, 6))},
        "vibration": None,
    }
    mh = out["moves_holds"]
    mh["relative_force"] = mh["rms_force_error_n"] / peak_f if peak_f > 0 else 0.0
    mh["relative_moment"] = mh["rms_moment_error_nm"] / peak_m if peak_m >= 0.01 * peak_f * moment_scale_m else None
    if in_vib.any():
        out["vibration"] = {"samples": int(in_vib.sum()), "rms_force_error_n": rms(err[in_vib], slice(0, 3)),
                            "rms_moment_error_nm": rms(err[in_vib], slice(3, 6))}
    out["guard"] = []
    for trip in guard_trips(signals):
        start = trip.trip_time_s
        end = start + trip.stop_duration_s + 0.5
        sel = (t >= start) & (t <= end)
        limit = trip.force_limit_n
        peak_est = float(np.linalg.norm(estimate[sel, :3], axis=1).max()) if sel.any() else float("nan")
        peak_app = float(np.linalg.norm(applied[sel, :3], axis=1).max()) if sel.any() else float("nan")
        out["guard"].append({
            "trip_time_s": start, "limit": trip.trip_limit, "force_limit_n": limit,
            "moment_limit_nm": trip.moment_limit_nm, "trip_force_n": trip.trip_force_n,
            "predicted_force_n": trip.predicted_force_n,
            "peak_estimated_force_n": peak_est, "peak_applied_force_n": peak_app,
            "overshoot": peak_est / limit - 1.0 if limit > 0 else float("nan"),
            "stop_duration_s": trip.stop_duration_s, "message": trip.message,
        })
    return out


def tissue_lines(summary: dict) -> list[str]:
    """The run summary's soft-tissue lines (estimate vs applied, guard trips, guarded moves); [] without tissue.

    Args:
        summary: the run summary ("tissue" from ``summarize_tissue``, "tissue_config", "guard_stops").

    Returns:
        Text lines (N, N m, s): the wrench estimate's errors, one per guard trip and one per guarded move.
    """
    tissue = summary.get("tissue")
    if not tissue:
        return []
    mh, vib = tissue["moves_holds"], tissue["vibration"]
    lines = [f"soft tissue ({summary.get('tissue_config')}): peak applied {tissue['peak_force_n']:.1f} N, "
             f"{tissue['peak_moment_nm']:.2f} N m; external-wrench estimate vs applied, RMS error in moves and holds "
             f"{mh['rms_force_error_n']:.3f} N ({mh['relative_force'] * 100:.3f} %), "
             f"{mh['rms_moment_error_nm']:.4f} N m"
             + (f" ({mh['relative_moment'] * 100:.3f} %)" if mh["relative_moment"] is not None
                else " (no moment to speak of)")
             + (f"; during the vibration {vib['rms_force_error_n']:.3f} N, {vib['rms_moment_error_nm']:.4f} N m"
                if vib else "")]
    for trip in tissue["guard"]:
        lines.append(f"force guard tripped at {trip['trip_time_s']:.3f} s ({trip['limit']}): estimated "
                     f"{trip['trip_force_n']:.1f} N, predicted {trip['predicted_force_n']:.1f} N; peak estimated "
                     f"{trip['peak_estimated_force_n']:.1f} N (applied {trip['peak_applied_force_n']:.1f} N) against "
                     f"guard_force_n {trip['force_limit_n']:g} N ({trip['overshoot'] * 100:+.1f} %); stopped over "
                     f"{trip['stop_duration_s']:.2f} s")
    for stop in summary.get("guard_stops", []):
        lines.append(f"guarded move to {np.round(stop['target'], 4).tolist()}: held "
                     f"{stop['short_of_target_m'] * 1e3:.2f} mm short of the target, as the scenario expects")
    return lines
