"""Summary of a suite run from its MCAP (pure: no rclpy): what the robot did against what was asked.

For each vibration step: the ground-truth platform vibration (direction and
amplitude error against the decomposition at the nominal pose), each leg's
measured vibration (actual hinge length leg_i + vib_i: amplitude against
|k_i| A, phase against 0/pi, frequency), and the leg-force model error
(legs/force_estimate against the emulator's measured efforts). For each move:
the ground-truth pose error after settling. Checked against the scenario bounds.

With a soft-tissue model: the external-wrench estimate against the wrench the emulator
applied (ground_truth/tissue_wrench), in moves and holds and during vibrations, and every force-guard
trip (kinematics/guard_status) with the peak load it let through.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..dynamics.newton_euler import leg_forces
from ..errors import MalformedMessageError
from ..kinematics.rotations import wrap_angle
from ..mcap_log.reader import RunFiles, RunReader, open_run
from ..messages.arrays import joint_arrays, pose_array, stamp_s
from ..messages.status_values import guard_status_from_cdr, integer, number, vibration_report_from_cdr
from ..motion.guard_status import GuardStatus
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


# topics a log recorded before the ground truth moved under ground_truth/ (old name -> new name)
LEGACY_TRUTH = {"platform/pose": "ground_truth/platform_pose", "platform/tissue_wrench": "ground_truth/tissue_wrench"}
STREAM_TOPICS = ("legs/joint_states", "ground_truth/platform_pose", "platform/pose_estimate", "legs/force_estimate",
                 "platform/external_wrench_estimate")  # the 500 Hz streams; the first is the input of the rest


# the type each status topic is read as; a log whose status has another type predates it (not read)
TYPED_STATUS = {"vibration/status": "stewart_vibration_interfaces/msg/VibrationUnitsStatus",
                "kinematics/guard_status": "stewart_vibration_interfaces/msg/ForceGuardStatus"}


def load_signals(mcap_path) -> dict:
    """Time series of a run (an MCAP file, a run folder: every file in it, in time order; or an open
    RunReader / RunFiles): ground-truth poses, joint states, force estimates (header-stamp times in s), the
    stream counts and the nodes' last diagnostics. Cut files are read as far as their chunks are whole.

    Args:
        mcap_path: an MCAP file or run folder path, or an open RunReader / RunFiles.

    Returns:
        {"pose": (times [n] (s), poses [n, 6] (m, rad)) the true poses, "joints": (times [n], {"position",
        "velocity", "effort": [n, 12]}, leg_1..6 then vib_1..6) the true joint states (ground_truth/joint_states;
        a log without them: legs/joint_states), "sensed_joints" (legs/joint_states: what the sensors read),
        "pose_estimate" (as "pose": the controller's estimate), "force_estimate": (times [n], {...: [n, 6]}),
        "vibration_starts": distinct vib window stamps (s), "stream_counts" (``counts_in_common_span``),
        "vibration_status" and "guard_status": the raw VibrationUnitsStatus and ForceGuardStatus messages (bytes;
        read with messages.status_values, which counts what is malformed), "untyped_statuses": {topic: count} of
        those recorded in another type (a log from before the typed statuses: left out), "node_diagnostics"
        (``last_diagnostics``), "tissue_wrench" and "wrench_estimate" (``wrench_array``), "clock": the /clock
        values (s) in recorded order, "stream_stamps" and "files" (``stream_stamps``)}.

    Raises:
        McapFileError: a path that is missing, a folder without .mcap files, or a file that is empty or not MCAP.
    """
    wanted: dict[str, list[Any]] = {
        "ground_truth/platform_pose": [], "ground_truth/joint_states": [], "legs/joint_states": [],
        "platform/pose_estimate": [], "legs/force_estimate": [], "vibration/joint_trajectory": [], "/diagnostics": [],
        "ground_truth/tissue_wrench": [], "platform/external_wrench_estimate": [], "/clock": [],
        **{old: [] for old in LEGACY_TRUTH}}
    raw_wanted: dict[str, list[bytes]] = {"vibration/status": [], "kinematics/guard_status": []}
    reader = mcap_path if isinstance(mcap_path, (RunReader, RunFiles)) else open_run(mcap_path, allow_truncated=True)
    stamps, files = stream_stamps(reader)
    counts = counts_in_common_span(stamps)
    def recorded(names):
        return [t.topic for t in reader.topics() if any(t.topic.endswith("/" + w) or t.topic == w for w in names)]

    for raw, msg in reader.decoded(recorded(wanted)):
        for key, bucket in wanted.items():
            if raw.topic.endswith("/" + key) or raw.topic == key:
                bucket.append(msg)
    untyped: dict[str, int] = {}
    for raw in reader.messages(recorded(raw_wanted)):  # read field by field: a spoofed status is counted
        for key, raw_bucket in raw_wanted.items():
            if raw.topic.endswith("/" + key) or raw.topic == key:
                if raw.type_name == TYPED_STATUS[key]:
                    raw_bucket.append(raw.data)
                else:  # a log from before the typed statuses (DiagnosticStatus): not read as one of them
                    untyped[key] = untyped.get(key, 0) + 1
    for old, new in LEGACY_TRUTH.items():  # a log from before the truth had its own topics
        wanted[new] = wanted[new] or wanted[old]
    sensed = joint_arrays(wanted["legs/joint_states"])
    return {
        "pose": pose_array(wanted["ground_truth/platform_pose"]),
        "joints": joint_arrays(wanted["ground_truth/joint_states"]) if wanted["ground_truth/joint_states"] else sensed,
        "sensed_joints": sensed,
        "pose_estimate": pose_array(wanted["platform/pose_estimate"]),
        "force_estimate": joint_arrays(wanted["legs/force_estimate"], names=LEG_NAMES),
        "vibration_starts": np.unique([stamp_s(m.header) for m in wanted["vibration/joint_trajectory"]]),
        "stream_counts": counts,
        "vibration_status": raw_wanted["vibration/status"],
        "node_diagnostics": last_diagnostics(wanted["/diagnostics"]),
        "tissue_wrench": wrench_array(wanted["ground_truth/tissue_wrench"]),
        "wrench_estimate": wrench_array(wanted["platform/external_wrench_estimate"]),
        "guard_status": raw_wanted["kinematics/guard_status"],
        "untyped_statuses": untyped,
        "clock": np.array([m.clock.sec + m.clock.nanosec * 1e-9 for m in wanted["/clock"]]),
        "stream_stamps": stamps,
        "files": files,
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


def stream_stamps(reader: RunReader | RunFiles) -> tuple[dict, list[dict]]:
    """Header stamps of every 500 Hz stream over every file, and what each file holds.

    Args:
        reader: the open run (one file or several).

    Returns:
        ({key of STREAM_TOPICS: stamps [n] (ns, int64, file after file)}, [{"file": name, "complete": bool,
        "states": legs/joint_states in it, "first_s", "last_s": its first and last state stamp (s, None
        without states)}] in time order).
    """
    names = {t.topic: key for t in reader.topics() for key in STREAM_TOPICS if t.topic.endswith("/" + key)}
    stamps: dict[str, list[int]] = {key: [] for key in STREAM_TOPICS}
    files = []
    for part in reader.files if isinstance(reader, RunFiles) else [reader]:
        states = stamps["legs/joint_states"]
        before = len(states)
        for raw in part.messages(list(names)):
            stamps[names[raw.topic]].append(raw.publish_time)
        mine = states[before:]
        files.append({"file": part.path.name, "complete": part.complete, "states": len(mine),
                      "first_s": min(mine) / 1e9 if mine else None, "last_s": max(mine) / 1e9 if mine else None})
    return {key: np.asarray(v, dtype=np.int64) for key, v in stamps.items()}, files


def counts_in_common_span(stamps: dict) -> dict:
    """Messages per 500 Hz topic whose stamps lie in the span every one of them covers (from the last
    first stamp to the first last stamp: start-up and shut-down are not losses).

    Args:
        stamps: {key of STREAM_TOPICS: stamps [n] (ns)} (``stream_stamps``).

    Returns:
        {key: message count}; all messages of each topic when one of them is missing.
    """
    present = [v for v in stamps.values() if v.size]
    if len(present) < len(STREAM_TOPICS):
        return {key: int(v.size) for key, v in stamps.items()}
    lo, hi = max(v.min() for v in present), min(v.max() for v in present)
    return {key: int(((v >= lo) & (v <= hi)).sum()) for key, v in stamps.items()}


GAP_FACTOR = 1.5  # a step between states longer than this many periods is a gap
MAX_GAPS_LISTED = 100  # gaps listed one by one (all are counted)
SPAN_START_MARGIN_S = 0.5  # the recorder is seen subscribed a moment before its subscription is matched
SPAN_END_MARGIN_S = 0.1  # the runner's clock at the recorder's stop may be this much ahead of its last state
# the 500 Hz output a node's restart interrupts (the recorder's: the recording itself)
NODE_OUTPUTS = {"hardware_emulator": "legs/joint_states", "kinematics": "platform/pose_estimate",
                "leg_force_estimator": "legs/force_estimate", "mcap_recorder": "legs/joint_states"}


def stream_gaps(stamps_ns, lo: float | None = None, hi: float | None = None) -> dict:
    """The gaps of one uniformly stamped stream over [lo, hi] (s; default its own first and last stamp).

    Args:
        stamps_ns: stamps [n] (ns), any order.
        lo: start of the span judged (s); a stream that starts later has a gap at the head.
        hi: end of the span judged (s); one that ends earlier has a gap at the tail.

    Returns:
        {"period_s": median step, "span_s": [lo, hi], "expected": samples the span holds at that period,
        "recorded": samples in it, "missing": samples not there, "gaps": [{"start_s", "end_s", "missing"}]
        (start/end: the last stamp before and the first after, or the span's edge; the first
        MAX_GAPS_LISTED), "gap_count": every gap}; with fewer than two stamps the period is NaN and nothing
        is expected.
    """
    t = np.sort(np.asarray(stamps_ns, dtype=np.int64)) / 1e9
    if t.size < 2:
        return {"period_s": float("nan"), "span_s": [lo, hi], "expected": 0, "recorded": int(t.size), "missing": 0,
                "gaps": [], "gap_count": 0}
    period = float(np.median(np.diff(t)))
    lo = float(t[0]) if lo is None else float(lo)
    hi = float(t[-1]) if hi is None else float(hi)
    inside = t[(t >= lo - 0.5 * period) & (t <= hi + 0.5 * period)]
    edges = np.concatenate([[lo - period], inside, [hi + period]])
    steps = np.diff(edges)
    missing = np.maximum(np.rint(steps / period).astype(int) - 1, 0)
    where = np.flatnonzero(steps > GAP_FACTOR * period)
    gaps = [{"start_s": float(max(edges[i], lo)), "end_s": float(min(edges[i + 1], hi)), "missing": int(missing[i])}
            for i in where[:MAX_GAPS_LISTED]]
    expected = int(round((hi - lo) / period)) + 1 if hi >= lo else 0
    return {"period_s": period, "span_s": [lo, hi], "expected": expected, "recorded": int(inside.size),
            "missing": int(missing[where].sum()), "gaps": gaps, "gap_count": int(where.size)}


def recording_coverage(signals: dict, span: tuple[float, float] | None = None) -> dict:
    """What the recording covers of the run: every file, and the gaps in legs/joint_states (the 500 Hz
    stream every state of the robot is on) over the run's span, within a file or between files.

    Args:
        signals: from ``load_signals`` (stream_stamps, files).
        span: (start, end) (sim s) the run was recorded over, as the runner saw it (from the recorder's
            readiness to its stop; judged from SPAN_START_MARGIN_S after the one to SPAN_END_MARGIN_S before
            the other); None: from the first to the last recorded state.

    Returns:
        ``stream_gaps`` of the joint states plus "files", "ratio" (recorded / expected; 0 if nothing) and
        "clock": ``stream_gaps`` of the recorded /clock values (None with fewer than two): its ticks the
        recording lost (printed; no figure needs them).
    """
    lo, hi = (None, None) if span is None else (span[0] + SPAN_START_MARGIN_S, span[1] - SPAN_END_MARGIN_S)
    out = stream_gaps(signals["stream_stamps"]["legs/joint_states"], lo, hi)
    out["files"] = signals.get("files", [])
    clock = np.asarray(signals.get("clock", np.empty(0)), float)
    out["clock"] = stream_gaps(np.rint(clock * 1e9).astype(np.int64), lo, hi) if clock.size > 1 else None
    out["ratio"] = out["recorded"] / out["expected"] if out["expected"] else 0.0
    return out


def restart_gaps(signals: dict, restarts: list[dict]) -> list[dict]:
    """The gap each restarted node left in its 500 Hz output (``NODE_OUTPUTS``).

    Args:
        signals: from ``load_signals`` (stream_stamps).
        restarts: {"node", "exit_code", "sim_time_s" (when its exit was seen, or None)} per restart.

    Returns:
        Per restart: the restart's keys plus "stream" (None for a node without such an output) and
        "gap_s": (its last stamp before the exit was seen, its first stamp after) (s), the end None when the
        output never came back; None when nothing can be measured.
    """
    out = []
    for restart in restarts:
        row = dict(restart, stream=NODE_OUTPUTS.get(restart["node"]), gap_s=None)
        when = restart.get("sim_time_s")
        stamps = signals["stream_stamps"].get(row["stream"]) if row["stream"] else None
        if stamps is not None and stamps.size and when is not None:
            t = np.sort(stamps) / 1e9
            before, after = t[t <= when], t[t > when]  # the node died before its exit was seen at ``when``
            if before.size:
                row["gap_s"] = (float(before[-1]), float(after[0]) if after.size else None)
        out.append(row)
    return out


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
        "refusals"} (of the last well-formed vibration status), "malformed_statuses": the recorded statuses
        that could not be read (messages.status_values), left out, "untyped_statuses": {topic: count} of
        statuses recorded in another type (a log from before the typed statuses), not read}.
    """
    counts = signals["stream_counts"]
    base = max(counts.get("legs/joint_states", 0), 1)
    topics = {topic: {"count": int(n), "ratio": n / base} for topic, n in counts.items()}
    nodes, malformed = {}, []
    for name, (level, message, values) in signals.get("node_diagnostics", {}).items():
        if "states_received" in values:
            try:
                nodes[name.split(":")[0]] = {
                    "received": integer(values, "states_received"), "lost": integer(values, "states_lost", missing=0),
                    "processed": integer(values, "states_processed", missing=0),
                    "lag_p50_ms": number(values, "states_lag_p50_ms", missing=0.0),
                    "lag_p99_ms": number(values, "states_lag_p99_ms", missing=0.0), "level": level, "message": message}
            except MalformedMessageError as exc:  # a status not of the node it names (recorded as it came)
                malformed.append(f"/diagnostics {name[:60]!r}: {exc}")
    reports = []
    for data in signals.get("vibration_status") or []:
        try:
            reports.append(vibration_report_from_cdr(data))
        except MalformedMessageError as exc:
            malformed.append(f"vibration/status: {exc}")
    windows = {"accepted": reports[-1].accepted if reports else 0, "refused": reports[-1].refused if reports else 0,
               "refusals": sorted({f"{r.event_outcome}: {r.event_reason}" for r in reports if r.event == "refused"})}
    derived = [topics[t]["ratio"] for t in ("platform/pose_estimate", "legs/force_estimate",
                                            "platform/external_wrench_estimate") if t in topics]
    return {"topics": topics, "nodes": nodes, "worst_ratio": min(derived) if derived else 0.0,
            "lost": sum(n["lost"] for n in nodes.values()), "windows": windows, "malformed_statuses": malformed,
            "untyped_statuses": dict(signals.get("untyped_statuses") or {})}


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


def check_bounds(summary: dict, bounds: dict) -> list[str]:
    """Human-readable list of every figure that missed its bound (empty = all passed).

    Every figure the run summary prints is judged here: pose errors after moves; per vibration the
    platform's direction, amplitude and off-axis ratio, every leg's amplitude, phase (and its sign) and
    frequency, the same platform figures and leg amplitudes in the controller's view (``controller_view``), the
    active duration and every leg's force error (the worst); with a tissue the wrench
    estimate and the guard trips; the robot's limits over the recorded states (``limit_check``); the sample
    ratio of every derived stream and, per node, its lost input states and its lag.

    Args:
        summary: the run summary ("moves", "vibrations", optional "tissue", "limits" (``limit_summary``) and
            "streams").
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
        for key, unit in (("fracture_displacement_mm", "mm"), ("fracture_angulation_deg", "deg"),
                          ("fracture_rotation_deg", "deg")):  # reduction accuracy, where the record has it
            if key in move and not move[key] <= bounds[key]:
                failures.append(f"move to {move['name']}: {key.replace('_', ' ').rsplit(' ', 1)[0]} "
                                f"{move[key]:.4f} {unit} at the fracture site (bound {bounds[key]:g})")
        # the controller's own view of the move (what the runner settled on), where the record has it
        believed = (move.get("estimate_error_m", 0.0), move.get("estimate_error_deg", 0.0))
        if not (believed[0] <= bounds["pose_error_m"] and believed[1] <= bounds["pose_error_deg"]):
            failures.append(f"move to {move['name']}: the controller's estimate is off by {believed[0] * 1e6:.2f} um "
                            f"/ {believed[1]:.4f} deg")
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
        view = vib.get("controller_view")
        if view is not None:  # what the controller believes it delivered, judged on the same bounds
            checks += [("direction error in the controller's view", view["direction_error_deg"],
                        bounds["direction_error_deg"], "deg"),
                       ("amplitude error in the controller's view", view["amplitude_error"], bounds["amplitude_error"],
                        ""),
                       ("off-axis ratio in the controller's view", view["off_axis_ratio"], bounds["off_axis_ratio"],
                        "")]
            if view.get("leg_amplitude_error") is not None:
                checks.append(("leg amplitude error in the controller's view (worst leg)",
                               float(np.max(view["leg_amplitude_error"])), bounds["leg_amplitude_error"], ""))
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
    for figure in summary.get("limits") or []:
        if figure["violations"]:
            failures.append(f"limits over the recorded states: {figure['line']}")
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


def limit_summary(robot: Robot, signals: dict) -> list[dict]:
    """The independent limit check (``limit_check.check_limits``) of the recorded states, as JSON-ready rows
    (the figure's fields plus its printed "line").

    Args:
        robot: the robot (limits and geometry from config/robot.yaml).
        signals: from ``load_signals`` (joints, pose, clock).

    Returns:
        One dict per figure.
    """
    from dataclasses import asdict

    from .limit_check import check_limits

    return [dict(asdict(f), line=f.line()) for f in check_limits(robot, signals["joints"], signals["pose"],
                                                                  signals.get("clock"))]


def recording_problems(coverage: dict, restarts: list[dict]) -> list[str]:
    """What the recording misses, one problem line each: every gap in the states (in a file, between files,
    at the head or tail of the run's span), every cut file, every restarted node with the gap it left.

    Args:
        coverage: ``recording_coverage``.
        restarts: ``restart_gaps``.

    Returns:
        Problem lines (empty: the recording covers the run).
    """
    problems = []
    for gap in coverage["gaps"]:
        problems.append(f"the recording has a gap from {gap['start_s']:.3f} s to {gap['end_s']:.3f} s "
                        f"({gap['end_s'] - gap['start_s']:.3f} s, {gap['missing']} states not recorded)")
    if coverage.get("gap_count", 0) > len(coverage["gaps"]):
        problems.append(f"... and {coverage['gap_count'] - len(coverage['gaps'])} more gaps "
                        f"({coverage['missing']} states not recorded in all)")
    for f in coverage["files"]:
        if not f["complete"]:
            problems.append(f"{f['file']} was cut short (no summary; its whole chunks are analysed; rebuild it "
                            "with stewart-vibration mcap-recover)")
    for r in restarts:
        gap = r.get("gap_s")
        what = (f"; its {r['stream']} stopped at {gap[0]:.3f} s and "
                + (f"resumed at {gap[1]:.3f} s ({gap[1] - gap[0]:.3f} s gap)" if gap[1] is not None
                   else "never resumed") if gap else
                f"; {'no 500 Hz output to measure its gap' if r['stream'] is None else 'its gap cannot be measured'}")
        when = f" at {r['sim_time_s']:.3f} s" if r.get("sim_time_s") is not None else ""
        problems.append(f"{r['node']} exited with code {r['exit_code']}{when} and was restarted{what}")
    return problems


def recording_lines(summary: dict) -> list[str]:
    """The run summary's lines on what the recording covers and on the limits (printed with the figures).

    Args:
        summary: the run summary ("recording": ``recording_coverage``, "limits": ``limit_summary``).

    Returns:
        Text lines.
    """
    lines = []
    rec = summary.get("recording")
    if rec:
        lo, hi = rec["span_s"]
        files = ", ".join(f"{f['file']} ({f['states']} states{'' if f['complete'] else ', cut'})" for f in rec["files"])
        span = f" over {lo:.3f}..{hi:.3f} s of sim time" if lo is not None and hi is not None else ""
        lines.append(f"recording: {len(rec['files'])} file(s): {files}; legs/joint_states {rec['recorded']} of "
                     f"{rec['expected']} states{span} ({rec['ratio'] * 100:.2f} %), "
                     f"{rec.get('gap_count', len(rec['gaps']))} gap(s)")
        clock = rec.get("clock")
        if clock and clock["missing"]:
            lines.append(f"  /clock: {clock['missing']} of {clock['expected']} ticks not recorded "
                         f"({clock['gap_count']} gaps)")
    if summary.get("limits"):
        lines.append("limits over the recorded states (independent check of the true joint states and "
                     "ground_truth/platform_pose):")
        lines += [f"  {f['line']}" for f in summary["limits"]]
    return lines
