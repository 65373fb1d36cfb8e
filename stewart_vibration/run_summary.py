"""Summary of a suite run from its MCAP (pure: no rclpy): what the robot did against what was asked.

For each vibration step: the ground-truth platform vibration (direction and
amplitude error against the decomposition at the nominal pose), each leg's
measured vibration (actual hinge length leg_i + vib_i: amplitude against
|k_i| A, phase against 0/pi, frequency), and the leg-force model error
(legs/force_estimate against the emulator's measured efforts). For each move:
the ground-truth pose error after settling. Checked against the scenario bounds.
"""

from __future__ import annotations

import numpy as np

from .analysis import (
    direction_error_deg,
    fit_sinusoid,
    force_error,
    leg_phase_offsets_deg,
    line_vibration,
    phase_error_to_0_or_pi_deg,
)
from .mcap_log.reader import RunReader
from .message_arrays import joint_arrays, pose_array, stamp_s
from .robot import Robot
from .vibration import decompose_vibration

STEADY_MARGIN_S = 0.2  # skip this much after the ramp-in and before the ramp-out


STREAM_TOPICS = ("legs/joint_states", "platform/pose", "platform/pose_estimate", "legs/force_estimate",
                 "platform/external_wrench_estimate")  # the 500 Hz streams; the first is the input of the rest


def load_signals(mcap_path) -> dict:
    """Time series from the run: ground-truth poses, joint states, force estimates (times in s), the stream
    counts and the nodes' last diagnostics."""
    wanted = {"platform/pose": [], "legs/joint_states": [], "legs/force_estimate": [],
              "vibration/joint_trajectory": [], "/diagnostics": [], "vibration/status": []}
    reader = RunReader(mcap_path)
    counts = stream_counts(reader)
    topics = [t.topic for t in reader.topics() if any(t.topic.endswith("/" + w) or t.topic == w for w in wanted)]
    for raw, msg in reader.decoded(topics):
        for key, bucket in wanted.items():
            if raw.topic.endswith("/" + key) or raw.topic == key:
                bucket.append(msg)
    return {
        "pose": pose_array(wanted["platform/pose"]),
        "joints": joint_arrays(wanted["legs/joint_states"]),
        "force_estimate": joint_arrays(wanted["legs/force_estimate"], names=[f"leg_{i}" for i in range(1, 7)]),
        "vibration_starts": np.unique([stamp_s(m.header) for m in wanted["vibration/joint_trajectory"]]),
        "stream_counts": counts,
        "vibration_status": [{kv.key: kv.value for kv in m.values} for m in wanted["vibration/status"]],
        "node_diagnostics": last_diagnostics(wanted["/diagnostics"]),
    }


def stream_counts(reader: RunReader) -> dict:
    """Messages per 500 Hz topic whose stamps lie in the span every one of them covers (from the last
    first stamp to the first last stamp: start-up and shut-down are not losses)."""
    names = {t.topic: key for t in reader.topics() for key in STREAM_TOPICS if t.topic.endswith("/" + key)}
    stamps = {key: [] for key in STREAM_TOPICS}
    for raw in reader.messages(list(names)):
        stamps[names[raw.topic]].append(raw.publish_time)
    present = [np.asarray(v) for v in stamps.values() if v]
    if len(present) < len(STREAM_TOPICS):
        return {key: len(v) for key, v in stamps.items()}
    lo, hi = max(v.min() for v in present), min(v.max() for v in present)
    return {key: int(((np.asarray(v) >= lo) & (np.asarray(v) <= hi)).sum()) for key, v in stamps.items()}


def last_diagnostics(arrays) -> dict:
    """{status name: (level, message, {key: value})} of the last DiagnosticStatus of each name."""
    out = {}
    for array in arrays:
        for status in array.status:
            out[status.name] = (int.from_bytes(status.level, "little") if isinstance(status.level, bytes)
                                else int(status.level), status.message, {kv.key: kv.value for kv in status.values})
    return out


def stream_summary(signals: dict) -> dict:
    """Per 500 Hz topic: messages and their ratio to legs/joint_states (every state should give one pose
    estimate, one force estimate and one wrench estimate); and what each node reported about its input
    (received, lost, processed, lag) in its last diagnostics."""
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
    a ramped vibration is duration - ramp)."""
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
    """The vibration's common start time t0 (sim s): the first vib window stamp from ``after`` - 1 s on."""
    starts = signals["vibration_starts"]
    later = starts[starts >= after - 1.0]  # the caller's clock may run ahead of the planner's
    if later.size == 0:
        raise ValueError(f"no vibration/joint_trajectory window stamped after {after:.3f} s in the run")
    return float(later[0])


def summarize_vibration(robot: Robot, signals: dict, nominal_pose, parameters: dict, start_time: float) -> dict:
    """Measured vs planned for one vibration step; ``start_time`` (sim s) is a lower bound of its t0
    (the planner stamps every window with t0, which the MCAP holds)."""
    params = dict(parameters)
    frequency = float(params.get("frequency_hz", 35.0))
    ramp, duration = float(params.get("ramp_s", 0.2)), float(params["duration_s"])
    plan = decompose_vibration(
        robot, nominal_pose, direction=params.get("direction"), frame=params.get("frame", "platform"),
        amplitude=params.get("amplitude_m") or None,
        acceleration_g=None if params.get("amplitude_m") else params.get("acceleration_g", 0.3),
        frequency=frequency, phase=float(params.get("phase_rad", 0.0)), method="linear")
    start = vibration_start(signals, start_time)
    t0 = start + ramp + STEADY_MARGIN_S
    t1 = start + duration - ramp - STEADY_MARGIN_S
    out = {"frequency_hz": frequency, "planned_amplitude_m": plan.amplitude, "planned_direction": plan.direction,
           "start_time_s": start, "window_s": [t0, t1], "gains": plan.gains}
    pt, poses = signals["pose"]
    sel = (pt >= t0) & (pt <= t1)
    line = line_vibration(pt[sel], poses[sel, :3], frequency)
    out.update({
        "measured_direction": line.direction,
        "direction_error_deg": direction_error_deg(line.direction, plan.direction),
        "measured_amplitude_m": line.amplitude,
        "amplitude_error": abs(line.amplitude / plan.amplitude - 1.0),
        "off_axis_ratio": line.off_axis_ratio,
        "window_samples": int(sel.sum()),
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
    leg_freq = frequency + np.angle(np.exp(1j * (second.phase - first.phase))) / (2 * np.pi * dt_halves)
    expected_offsets = np.degrees(np.angle(np.exp(1j * (plan.leg_phases - plan.leg_phases[np.argmax(fit.amplitude)]))))
    out.update({
        "leg_amplitude_m": fit.amplitude,
        "leg_amplitude_expected_m": plan.leg_amplitudes,
        "leg_amplitude_error": np.abs(fit.amplitude / plan.leg_amplitudes - 1.0),
        "leg_phase_deg": offsets,
        "leg_phase_expected_deg": expected_offsets,
        "leg_phase_error_deg": phase_error_to_0_or_pi_deg(offsets),
        "leg_phase_sign_ok": bool(np.all(np.abs(np.angle(np.exp(1j * np.radians(offsets - expected_offsets))))
                                         < np.radians(90))),
        "leg_frequency_hz": leg_freq,
        "leg_frequency_spread_hz": float(np.ptp(leg_freq)),
    })
    planned_active = duration - ramp
    measured_active = active_duration(jt, joints["position"][:, 6:12], plan.leg_amplitudes, frequency, start,
                                      start + duration + 1.0)
    out.update({"active_duration_s": measured_active, "planned_active_duration_s": planned_active,
                "active_duration_error_s": abs(measured_active - planned_active)})
    ft, forces = signals["force_estimate"]
    fsel = (ft >= t0) & (ft <= t1)
    if fsel.sum() >= 4:
        out["force"] = force_error(ft[fsel], forces["effort"][fsel], jt[sel], joints["effort"][sel, :6], frequency)
    else:
        out["force"] = None
    return out


def check_bounds(summary: dict, bounds: dict) -> list[str]:
    """Human-readable list of every figure that missed its bound (empty = all passed)."""
    failures = []
    for move in summary["moves"]:
        if move["pose_error_m"] > bounds["pose_error_m"] or move["pose_error_deg"] > bounds["pose_error_deg"]:
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
    streams = summary.get("streams")
    if streams is not None:
        if not streams["worst_ratio"] >= bounds["sample_ratio_min"]:
            failures.append(f"estimates per joint state {streams['worst_ratio']:.5f} below "
                            f"{bounds['sample_ratio_min']:g} (samples lost: {streams['lost']})")
        for node, row in streams["nodes"].items():
            if row["lost"]:
                failures.append(f"{node} lost {row['lost']} of its input states")
    return failures
