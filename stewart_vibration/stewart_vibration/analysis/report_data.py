"""What the run report draws and summarises, read from a run (pure: no rclpy): every whole-run series as its
envelope, the mean leg lengths and platform position, the span where the vibration units are active, the leg-force
model's error over the whole run, and the steady vibration's own samples at full rate.

A run is read twice, and held in neither: the first pass computes the whole-run figures as the recording streams
past (``report_scan``), the second keeps the states of the steady vibration only (``load_signals(windows=...)``).
A run no longer than two analysed spans (``held_whole``) is read once and held, and so is a run with an applied
tissue wrench (the tissue figures compare every estimate with the applied
wrench, and the force error takes the tissue's leg forces out at every state); the same reducers then take the
whole arrays at once. Times are s from the run's first message (its log time), as the plots show them.
"""

from __future__ import annotations

import numpy as np

from ..mcap_log.reader import RunFiles, RunReader
from ..robot import Robot
from .report_scan import ForceErrorScan, RunningMean, StreamEnvelope, VibrationActivity
from .run_signals import TISSUE_KEYS, load_signals, recorded_keys, truth_key
from .tissue_figures import guard_trips
from .vibration_figures import leg_force_error

RAMP_TRIM_S = 0.25  # trimmed from both ends of the active span (the ramps) when it is longer than 4 of them
WINDOW_MARGIN_S = 0.5  # s of states read beyond the steady window in the second pass
ANALYSED_MAX_S = 60.0  # the steady vibration's figures are fitted over its middle minute at most
TRUTH_STATES = ("ground_truth/joint_states", "legs/joint_states")  # the measured efforts, or a log's sensed ones
UNREAD = ("platform/pose_estimate", "/clock", "vibration/joint_trajectory")  # nothing in the report reads them
UNREAD_WITHOUT_TISSUE = (*UNREAD, "platform/external_wrench_estimate")  # compared with an applied tissue wrench only


class _Reducers:
    """The whole-run figures of the report, fed each stream's batches (absolute header-stamp times, s)."""

    def __init__(self, origin: float, measured_from_sensed: bool):
        self.origin, self.measured_from_sensed = origin, measured_from_sensed
        self.envelopes = {key: StreamEnvelope(width) for key, width in
                          (("leg", 6), ("vib", 6), ("force", 6), ("est", 6), ("pose", 3))}
        self.leg_mean, self.pose_mean = RunningMean(6), RunningMean(3)
        self.activity = VibrationActivity()
        self.force_error = ForceErrorScan()

    def _add(self, key: str, t: np.ndarray, values: np.ndarray, finite_only: bool = True) -> np.ndarray:
        kept = np.isfinite(values).all(axis=1) if finite_only else np.ones(len(t), bool)
        self.envelopes[key].add(t[kept] - self.origin, values[kept])
        return kept

    def sensed(self, t, columns: dict) -> None:
        """legs/joint_states: the leg lengths, unit displacements and measured forces as the sensors read them."""
        position, effort = columns["position"], columns["effort"]
        kept = self._add("leg", t, position[:, :6])
        self.leg_mean.add(position[kept, :6])
        kept = self._add("vib", t, position[:, 6:12])
        self.activity.add(t[kept] - self.origin, position[kept, 6:12])
        self._add("force", t, effort[:, :6])
        if self.measured_from_sensed:
            self.force_error.add_measured(t, effort[:, :6])

    def truth(self, t, columns: dict) -> None:
        """ground_truth/joint_states: the measured efforts the force estimate is judged against."""
        self.force_error.add_measured(t, columns["effort"][:, :6])

    def estimates(self, t, columns: dict) -> None:
        """legs/force_estimate."""
        self._add("est", t, columns["effort"])
        self.force_error.add_estimates(t, columns["effort"])

    def pose(self, t, poses) -> None:
        """The true platform pose: its position."""
        self._add("pose", t, poses[:, :3], finite_only=False)
        self.pose_mean.add(poses[:, :3])

    def sinks(self, recorded: set[str]) -> dict:
        """{topic key: callable} for ``load_signals``."""
        out = {"legs/joint_states": self.sensed, "legs/force_estimate": self.estimates,
               truth_key(recorded, "ground_truth/platform_pose", "platform/pose"): self.pose}
        if not self.measured_from_sensed:
            out["ground_truth/joint_states"] = self.truth
        return out


def _window(span: tuple[float, float] | None) -> tuple[float, float] | None:
    """The steady part of the active span (s): RAMP_TRIM_S less at both ends when it is long enough."""
    if span is None:
        return None
    t0, t1 = span
    return (t0 + RAMP_TRIM_S, t1 - RAMP_TRIM_S) if t1 - t0 > 4 * RAMP_TRIM_S else (t0, t1)


def analysed_span(window: tuple[float, float] | None) -> tuple[float, float] | None:
    """The part of the steady vibration (s) its figures are fitted over: all of it, or its middle ANALYSED_MAX_S
    (a therapy session vibrates for up to an hour: its samples are not held at once)."""
    if window is None or window[1] - window[0] <= ANALYSED_MAX_S:
        return window
    middle = 0.5 * (window[0] + window[1])
    return middle - 0.5 * ANALYSED_MAX_S, middle + 0.5 * ANALYSED_MAX_S


def held_whole(reader: RunReader | RunFiles) -> bool:
    """Whether a run is short enough to be read once and held: its recording (log time, its first file's first
    message to its last file's last) lasts at most two ANALYSED_MAX_S. The second pass would hold about half as
    much, and reading a short run again costs its report a quarter of its time."""
    files = reader.files if isinstance(reader, RunFiles) else [reader]
    return max(r.end_ns for r in files) - min(r.start_ns for r in files) <= 2 * ANALYSED_MAX_S * 1e9


def _window_samples(signals: dict, window: tuple[float, float], origin: float) -> dict:
    """The steady vibration's samples (times s from the first message), as the plots and fits read them."""
    out = {}
    (st, sensed), (et, estimate), (pt, poses) = signals["sensed_joints"], signals["force_estimate"], signals["pose"]
    for key, t, values in (("vib", st, sensed["position"][:, 6:12]), ("force", st, sensed["effort"][:, :6]),
                           ("est", et, estimate["effort"]), ("pose", pt, poses[:, :3])):
        rel = t - origin
        sel = (rel >= window[0]) & (rel <= window[1])
        if key != "pose":
            sel &= np.isfinite(values).all(axis=1)
        out[f"{key}_t"], out[key] = rel[sel], values[sel]
    return out


def report_data(reader: RunReader | RunFiles, robot: Robot) -> tuple[dict, dict]:
    """The report's data of a run, and the signals that cover its steady vibration.

    Returns:
        (data, signals). data: "time_origin_s", "time_origin_ns": the first message's log time (s, ns); per
        series present, its envelope (``report_scan.StreamEnvelope``) as "leg_t"/"leg_lengths", "vib_t"/"vib",
        "force_t"/"force", "est_t"/"est" (legs/joint_states' lengths, unit displacements and measured forces,
        the force estimates: [n, 6]) and "pose_t"/"pose_xyz" (the true position [n, 3], m); "leg_length_mean"
        [6], "pose_mean" [3]; "vibration_window": (start, end) of the steady vibration or None;
        "analysed_window": the part of it its figures are fitted over (``analysed_span``); "window": its
        samples {"vib_t", "vib", "force_t", "force", "est_t", "est", "pose_t", "pose"}; "force_error": the
        leg-force error over the whole run (``vibration_figures.leg_force_error``) or None; with a tissue wrench
        "wrench_applied(_t)", "wrench_estimated(_t)" [n, 6]; "guard_trips". signals: ``load_signals``' of the
        run (whole with tissue or when it is short, else around the steady vibration).
    """
    first = next(iter(reader.messages()), None)
    origin_ns = first.log_time if first is not None else 0
    origin = origin_ns / 1e9
    recorded = recorded_keys(reader, (*TISSUE_KEYS, *TRUTH_STATES, "ground_truth/platform_pose"))
    reducers = _Reducers(origin, measured_from_sensed="ground_truth/joint_states" not in recorded)
    tissue = bool(recorded.intersection(TISSUE_KEYS))
    held = not tissue and held_whole(reader)
    if tissue:
        signals = load_signals(reader, coverage=False, skip=UNREAD)
        for key, sink in reducers.sinks(recorded).items():
            sink(*{"legs/joint_states": signals["sensed_joints"], "ground_truth/joint_states": signals["joints"],
                   "legs/force_estimate": signals["force_estimate"]}.get(key, signals["pose"]))
        force_error = leg_force_error(robot, signals, -np.inf, np.inf, None)
    else:  # the reducers take the run as it streams past; a short run is held too (windows=None), a long one not
        signals = load_signals(reader, windows=None if held else [], sinks=reducers.sinks(recorded), coverage=False,
                               skip=UNREAD_WITHOUT_TISSUE)
        force_error = reducers.force_error.result()
    window = _window(reducers.activity.span())
    analysed = analysed_span(window)
    if analysed is not None and not (tissue or held):
        signals = load_signals(reader, windows=[(analysed[0] + origin - WINDOW_MARGIN_S,
                                                 analysed[1] + origin + WINDOW_MARGIN_S)], coverage=False,
                               skip=UNREAD_WITHOUT_TISSUE)
    data: dict = {"time_origin_s": origin, "time_origin_ns": origin_ns, "vibration_window": window,
                  "analysed_window": analysed,
                  "force_error": force_error, "leg_length_mean": reducers.leg_mean.result(),
                  "pose_mean": reducers.pose_mean.result()}
    for key, name in (("leg", "leg_lengths"), ("vib", "vib"), ("force", "force"), ("est", "est"), ("pose", "pose_xyz")):
        if reducers.envelopes[key].samples:
            data[f"{key}_t"], data[name] = reducers.envelopes[key].result()
    if analysed is not None:
        data["window"] = _window_samples(signals, analysed, origin)
    for key, name in (("applied", "tissue_wrench"), ("estimated", "wrench_estimate")):
        t, wrench = signals[name]
        if tissue and t.size and (key == "applied" or "wrench_applied" in data):
            data[f"wrench_{key}_t"], data[f"wrench_{key}"] = t - origin, wrench
    if signals["guard_status"]:
        data["guard_trips"] = [dict(trip.record(), t_s=trip.trip_time_s - origin)
                               for trip in guard_trips({"guard_status": signals["guard_status"]})]
    return data, signals
