"""Summary of a suite run from its MCAP (pure: no rclpy): what the robot did against what was asked.

For each vibration step: the ground-truth platform vibration (direction and
amplitude error against the decomposition at the nominal pose), each leg's
measured vibration (actual hinge length leg_i + vib_i: amplitude against
|k_i| A, phase against 0/pi, frequency), and the leg-force model error
(legs/force_estimate against the emulator's measured efforts). For each move:
the ground-truth pose error after settling. Checked against the scenario bounds.

With a soft-tissue model (issue 17): the external-wrench estimate against the wrench the emulator
applied (platform/tissue_wrench), in moves and holds and during vibrations, and every force-guard
trip (kinematics/guard_status) with the peak load it let through.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..dynamics.newton_euler import leg_forces
from ..kinematics.rotations import wrap_angle
from ..mcap_log.reader import RunReader
from ..messages.arrays import joint_arrays, pose_array, stamp_s
from ..robot import LEG_NAMES, Robot
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

STEADY_MARGIN_S = 0.2  # skip this much after the ramp-in and before the ramp-out


STREAM_TOPICS = ("legs/joint_states", "platform/pose", "platform/pose_estimate", "legs/force_estimate",
                 "platform/external_wrench_estimate")  # the 500 Hz streams; the first is the input of the rest


def load_signals(mcap_path) -> dict:
    """Time series of a run (an MCAP file path or an open RunReader): ground-truth poses, joint
    states, force estimates (header-stamp times in s), the stream counts and the nodes' last diagnostics.

    Args:
        mcap_path: an MCAP file path or an open RunReader.

    Returns:
        {"pose": (times [n] (s), poses [n, 6] (m, rad)), "joints": (times [n], {"position", "velocity",
        "effort": [n, 12]}, leg_1..6 then vib_1..6), "force_estimate": (times [n], {...: [n, 6]}),
        "vibration_starts": distinct vib window stamps (s), "stream_counts" (``stream_counts``),
        "vibration_status": [{key: value}], "node_diagnostics" (``last_diagnostics``), "tissue_wrench" and
        "wrench_estimate" (``wrench_array``), "guard_status": [({key: value}, message)]}.

    Raises:
        McapFileError: a path that is missing, not a regular file (a folder included), empty or not MCAP.
    """
    wanted: dict[str, list[Any]] = {"platform/pose": [], "legs/joint_states": [], "legs/force_estimate": [],
              "vibration/joint_trajectory": [], "/diagnostics": [], "vibration/status": [],
              "platform/tissue_wrench": [], "platform/external_wrench_estimate": [], "kinematics/guard_status": []}
    reader = mcap_path if isinstance(mcap_path, RunReader) else RunReader(mcap_path)
    counts = stream_counts(reader)
    topics = [t.topic for t in reader.topics() if any(t.topic.endswith("/" + w) or t.topic == w for w in wanted)]
    for raw, msg in reader.decoded(topics):
        for key, bucket in wanted.items():
            if raw.topic.endswith("/" + key) or raw.topic == key:
                bucket.append(msg)
    return {
        "pose": pose_array(wanted["platform/pose"]),
        "joints": joint_arrays(wanted["legs/joint_states"]),
        "force_estimate": joint_arrays(wanted["legs/force_estimate"], names=LEG_NAMES),
        "vibration_starts": np.unique([stamp_s(m.header) for m in wanted["vibration/joint_trajectory"]]),
        "stream_counts": counts,
        "vibration_status": [{kv.key: kv.value for kv in m.values} for m in wanted["vibration/status"]],
        "node_diagnostics": last_diagnostics(wanted["/diagnostics"]),
        "tissue_wrench": wrench_array(wanted["platform/tissue_wrench"]),
        "wrench_estimate": wrench_array(wanted["platform/external_wrench_estimate"]),
        "guard_status": [({kv.key: kv.value for kv in m.values}, m.message) for m in wanted["kinematics/guard_status"]],
    }


def wrench_array(messages) -> tuple[np.ndarray, np.ndarray]:
    """WrenchStamped messages -> (times [n] s, wrenches [n, 6] = [force N, torque N m]).

    Args:
        messages: WrenchStamped messages.

    Returns:
        (header-stamp times [n] (s), wrenches [n, 6] [force N; torque N m]); empty arrays without messages.
    """
    if not messages:
        return np.empty(0), np.empty((0, 6))
    times = np.array([stamp_s(m.header) for m in messages])
    values = np.array([[m.wrench.force.x, m.wrench.force.y, m.wrench.force.z,
                        m.wrench.torque.x, m.wrench.torque.y, m.wrench.torque.z] for m in messages])
    return times, values


def stream_counts(reader: RunReader) -> dict:
    """Messages per 500 Hz topic whose stamps lie in the span every one of them covers (from the last
    first stamp to the first last stamp: start-up and shut-down are not losses).

    Args:
        reader: the open run.

    Returns:
        {key of STREAM_TOPICS: message count}; all messages of each topic when one of them is missing.
    """
    names = {t.topic: key for t in reader.topics() for key in STREAM_TOPICS if t.topic.endswith("/" + key)}
    stamps: dict[str, list[int]] = {key: [] for key in STREAM_TOPICS}
    for raw in reader.messages(list(names)):
        stamps[names[raw.topic]].append(raw.publish_time)
    present = [np.asarray(v) for v in stamps.values() if v]
    if len(present) < len(STREAM_TOPICS):
        return {key: len(v) for key, v in stamps.items()}
    lo, hi = max(v.min() for v in present), min(v.max() for v in present)
    return {key: int(((np.asarray(v) >= lo) & (np.asarray(v) <= hi)).sum()) for key, v in stamps.items()}


def last_diagnostics(arrays) -> dict:
    """{status name: (level, message, {key: value})} of the last DiagnosticStatus of each name.

    Args:
        arrays: DiagnosticArray messages, in time order.

    Returns:
        {status name: (level as int, message, {key: value})}.
    """
    out = {}
    for array in arrays:
        for status in array.status:
            out[status.name] = (int.from_bytes(status.level, "little") if isinstance(status.level, bytes)
                                else int(status.level), status.message, {kv.key: kv.value for kv in status.values})
    return out


def stream_summary(signals: dict) -> dict:
    """Per 500 Hz topic: messages and their ratio to legs/joint_states (every state should give one pose
    estimate, one force estimate and one wrench estimate); and what each node reported about its input
    (received, lost, processed, lag) in its last diagnostics.

    Args:
        signals: from ``load_signals`` (stream_counts, node_diagnostics, vibration_status).

    Returns:
        {"topics": {topic: {"count", "ratio"}}, "nodes": {node: {"received", "lost", "processed",
        "lag_p50_ms", "lag_p99_ms", "level", "message"}}, "worst_ratio": the lowest ratio of the derived
        streams (0.0 if none), "lost": states lost over all nodes, "windows": {"accepted", "refused",
        "refusals"}}.

    Raises:
        ValueError: a count or lag in a node's diagnostics or the vibration status is not a number.
    """
    counts = signals["stream_counts"]
    base = max(counts.get("legs/joint_states", 0), 1)
    topics = {topic: {"count": int(n), "ratio": n / base} for topic, n in counts.items()}
    nodes = {}
    for name, (level, message, values) in signals.get("node_diagnostics", {}).items():
        if "states_received" in values:
            nodes[name.split(":")[0]] = {
                "received": int(values["states_received"]), "lost": int(values.get("states_lost", 0)),
                "processed": int(values.get("states_processed", 0)),
                "lag_p50_ms": float(values.get("states_lag_p50_ms", 0)),
                "lag_p99_ms": float(values.get("states_lag_p99_ms", 0)), "level": level, "message": message}
    status = signals.get("vibration_status") or [{}]
    windows = {"accepted": int(status[-1].get("accepted_windows", 0) or 0),
               "refused": int(status[-1].get("refused_windows", 0) or 0),
               "refusals": sorted({s.get("event", "") for s in status if s.get("event", "").startswith("refused")})}
    derived = [topics[t]["ratio"] for t in ("platform/pose_estimate", "legs/force_estimate",
                                            "platform/external_wrench_estimate") if t in topics]
    return {"topics": topics, "nodes": nodes, "worst_ratio": min(derived) if derived else 0.0,
            "lost": sum(n["lost"] for n in nodes.values()), "windows": windows}


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
    """The vibration's common start time t0 (sim s): the first vib window stamp from ``after`` - 1 s on.

    Args:
        signals: from ``load_signals`` (vibration_starts, s).
        after: a lower bound of t0 (sim s).

    Returns:
        t0 (sim s).

    Raises:
        ValueError: no vibration/joint_trajectory window is stamped at or after ``after`` - 1 s.
    """
    starts = signals["vibration_starts"]
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
                         "not run, or the log holds no platform/pose for it)")
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
        settings: the settings the planner reports it ran (its start answer: every key of
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
    return out


def tissue_leg_forces(robot: Robot, signals: dict, times) -> np.ndarray | float:
    """The axial forces [n, 6] (N) the applied tissue wrench (platform/tissue_wrench, ground truth) puts on the
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


def guard_trips(signals: dict) -> list[dict]:
    """Every force-guard trip in kinematics/guard_status (the last status of each trip: its final peaks).

    Args:
        signals: from ``load_signals`` (guard_status: [({key: value}, message)]).

    Returns:
        One dict per trip (its status values plus "message"), in order of trip_time_s.
    """
    trips = {}
    for values, message in signals.get("guard_status", []):
        if values.get("state") == "tripped" and "trip_time_s" in values:
            trips[values["trip_time_s"]] = dict(values, message=message)
    return [trips[k] for k in sorted(trips, key=float)]


def summarize_tissue(signals: dict, vibrations=(), moment_scale_m: float = 0.1) -> dict | None:
    """External-wrench estimate vs the applied tissue wrench (None without platform/tissue_wrench).

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
        start = float(trip["trip_time_s"])
        stop = trip.get("stop_duration_s", "0").split()[0]
        end = start + float(stop) + 0.5
        sel = (t >= start) & (t <= end)
        limit = float(trip.get("force_limit_n", "nan"))
        peak_est = float(np.linalg.norm(estimate[sel, :3], axis=1).max()) if sel.any() else float("nan")
        peak_app = float(np.linalg.norm(applied[sel, :3], axis=1).max()) if sel.any() else float("nan")
        out["guard"].append({
            "trip_time_s": start, "limit": trip.get("trip_limit"), "force_limit_n": limit,
            "moment_limit_nm": float(trip.get("moment_limit_nm", "nan")),
            "trip_force_n": float(trip.get("trip_force_n", "nan")),
            "predicted_force_n": float(trip.get("predicted_force_n", "nan")),
            "peak_estimated_force_n": peak_est, "peak_applied_force_n": peak_app,
            "overshoot": peak_est / limit - 1.0 if limit > 0 else float("nan"),
            "stop_duration_s": float(stop), "message": trip.get("message", ""),
        })
    return out


def check_bounds(summary: dict, bounds: dict) -> list[str]:
    """Human-readable list of every figure that missed its bound (empty = all passed).

    Every figure the run summary prints is judged here: pose errors after moves; per vibration the
    platform's direction, amplitude and off-axis ratio, every leg's amplitude, phase (and its sign) and
    frequency, the active duration and every leg's force error (the worst); with a tissue the wrench
    estimate and the guard trips; the sample ratio of every derived stream and, per node, its lost input
    states and its lag.

    Args:
        summary: the run summary ("moves", "vibrations", optional "tissue" and "streams").
        bounds: the scenario's bounds (SI units, deg for angles); wrench_error_relative (0.02),
            wrench_error_vibration_n (1 N) and guard_overshoot (0.1) have defaults.

    Returns:
        One line per missed bound (a NaN figure misses too); [] if all passed.

    Raises:
        KeyError: a required bound or figure is missing.
    """
    failures = []
    for move in summary["moves"]:
        if not (move["pose_error_m"] <= bounds["pose_error_m"] and move["pose_error_deg"] <= bounds["pose_error_deg"]):
            failures.append(f"move to {move['name']}: pose error {move['pose_error_m'] * 1e6:.2f} um / "
                            f"{move['pose_error_deg']:.4f} deg")
    for i, vib in enumerate(summary["vibrations"], start=1):
        checks = [
            ("direction error", vib["direction_error_deg"], bounds["direction_error_deg"], "deg"),
            ("amplitude error", vib["amplitude_error"], bounds["amplitude_error"], ""),
            ("off-axis ratio", vib["off_axis_ratio"], bounds["off_axis_ratio"], ""),
            ("leg amplitude error (worst leg)", float(np.max(vib["leg_amplitude_error"])),
             bounds["leg_amplitude_error"], ""),
            ("leg phase error", float(np.max(vib["leg_phase_error_deg"])), bounds["leg_phase_error_deg"], "deg"),
            ("leg frequency spread", vib["leg_frequency_spread_hz"], bounds["leg_frequency_spread_hz"], "Hz"),
            ("leg frequency error (worst leg)", vib["leg_frequency_error_hz"], bounds["leg_frequency_error_hz"], "Hz"),
            ("active duration error", vib["active_duration_error_s"], bounds["active_duration_error_s"], "s"),
        ]
        if vib["force"] is not None:
            checks.append(("force RMS error / amplitude", vib["force"]["worst_leg_relative"],
                           bounds["force_rms_relative"], ""))
        else:
            failures.append(f"vibration {i}: no force estimates recorded")
        for name, value, bound, unit in checks:
            if not value <= bound:
                failures.append(f"vibration {i}: {name} {value:.4g} {unit} exceeds {bound:g} {unit}")
        if not vib["leg_phase_sign_ok"]:
            failures.append(f"vibration {i}: a leg vibrates in the wrong phase (0 vs pi)")
    tissue = summary.get("tissue")
    if tissue is not None:
        mh, limit = tissue["moves_holds"], bounds.get("wrench_error_relative", 0.02)
        for name, value in (("force", mh["relative_force"]), ("moment", mh["relative_moment"])):
            if value is not None and not value <= limit:
                failures.append(f"external-wrench estimate in moves and holds: RMS {name} error {value * 100:.3f} % "
                                f"of the peak applied exceeds {limit * 100:g} %")
        vib, vib_limit = tissue["vibration"], bounds.get("wrench_error_vibration_n", 1.0)
        if vib is not None and not vib["rms_force_error_n"] <= vib_limit:
            failures.append(f"external-wrench estimate during the vibration: RMS force error "
                            f"{vib['rms_force_error_n']:.3f} N exceeds {vib_limit:g} N")
        for trip in tissue["guard"]:
            if trip["limit"] == "force" and not trip["overshoot"] <= bounds.get("guard_overshoot", 0.1):
                failures.append(f"force guard at {trip['trip_time_s']:.3f} s: peak estimated force "
                                f"{trip['peak_estimated_force_n']:.1f} N is {trip['overshoot'] * 100:.1f} % over "
                                f"guard_force_n {trip['force_limit_n']:g} N")
    streams = summary.get("streams")
    if streams is not None:
        if not streams["worst_ratio"] >= bounds["sample_ratio_min"]:
            failures.append(f"estimates per joint state {streams['worst_ratio']:.5f} below "
                            f"{bounds['sample_ratio_min']:g} (samples lost: {streams['lost']})")
        for node, row in streams["nodes"].items():
            if row["lost"]:
                failures.append(f"{node} lost {row['lost']} of its input states")
            if not row["lag_p99_ms"] <= bounds["stream_lag_p99_ms"]:
                failures.append(f"{node}: lag p99 {row['lag_p99_ms']:.1f} ms exceeds "
                                f"{bounds['stream_lag_p99_ms']:g} ms")
    return failures


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
