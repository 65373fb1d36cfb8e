"""A long vibration read without holding it (pure: no rclpy): its two ends are held, as a short vibration is
whole, and its middle is summed as the run streams past, into the sums every figure of ``summarize_vibration``
is computed from (sine fits as normal equations, the period peaks of the units, the leg-force error).

A vibration of an hour holds two EDGE_S ends of 500 Hz states instead of 1.8 M of them; its figures are the
ones of the whole vibration held (to rounding: ``SineSums``). Times are header stamps in sim s.
"""

from __future__ import annotations

import numpy as np

from ..mcap_log.reader import RunFiles, RunReader, open_run
from ..vibration.sine_fit import SineSums
from .report_scan import ForceErrorScan
from .run_signals import load_signals, merged_sinks, recorded_keys, truth_key
from .vibration_figures import VibrationFrame, period_peaks

STREAMED_FROM_S = 60.0  # a vibration longer than this (s, both ramps included) has its middle streamed
EDGE_S = 10.0  # s held at each end of a streamed vibration: its start is found up to 1 s before the record's


def streamed_span(start: float, duration: float) -> tuple[float, float] | None:
    """The span (lo, hi) (sim s, both excluded) of a vibration starting at ``start`` (s) for ``duration`` (s)
    whose states are summed rather than held; None for a vibration of STREAMED_FROM_S or less."""
    if duration <= STREAMED_FROM_S:
        return None
    return start + EDGE_S, start + duration - EDGE_S


def held_windows(vibrations, margin: float, streaming: bool = True):
    """The spans of states a run summary holds for its ``vibrations`` [(start, duration)] (sim s): each vibration
    with ``margin`` (s) either side, less its streamed span (``streamed_span``; none when not ``streaming``: a
    run with an applied tissue wrench, whose figures need every state).

    Returns:
        (windows [(t0, t1)] for ``load_signals``, the streamed span of each vibration or None).
    """
    windows, spans = [], []
    for start, duration in vibrations:
        span = streamed_span(start, duration) if streaming else None
        lo, hi = start - margin, start + duration + margin
        windows += [(lo, hi)] if span is None else [(lo, span[0]), (span[1], hi)]
        spans.append(span)
    return windows, spans


def stream_steady(run, frames: list) -> list:
    """The SteadyStream of each (VibrationFrame, streamed span or None) in ``frames`` (None where nothing is
    streamed), from a second read of the run (an MCAP, a run folder or an open RunReader / RunFiles) that holds
    nothing of its 500 Hz streams."""
    streams = [SteadyStream(frame, span) if span is not None else None for frame, span in frames]
    if not any(streams):
        return streams
    reader = run if isinstance(run, (RunReader, RunFiles)) else open_run(run, allow_truncated=True)
    recorded = recorded_keys(reader, ("ground_truth/joint_states", "ground_truth/platform_pose"))
    keys = (truth_key(recorded, "ground_truth/joint_states", "legs/joint_states"),
            truth_key(recorded, "ground_truth/platform_pose", "platform/pose"))
    feeds: list[dict] = []
    for stream in streams:
        feeds += stream.sinks(*keys) if stream is not None else []
    load_signals(reader, windows=[], sinks=merged_sinks(feeds), coverage=False)
    return streams


class SteadyStream:
    """The sums of one vibration's states inside ``span`` (lo < t < hi: the ones not held), as
    ``summarize_vibration`` takes them (``streamed``): sine fits over the steady window of the true poses, the
    true hinge lengths (whole window and each half), the pose estimates and the sensed hinge lengths; the units'
    period peaks over the active span; the leg-force error (the true efforts against the force estimates)."""

    def __init__(self, frame: VibrationFrame, span: tuple[float, float]):
        self.frame, self.span = frame, span
        f, window = frame.frequency, frame.window
        self.pose, self.estimate = SineSums(f, 3, window), SineSums(f, 3, window)
        self.sensed = SineSums(f, 6, window)
        self.first, self.second = SineSums(f, 6, window), SineSums(f, 6, window)
        self.peaks, self.peak_samples = period_peaks(np.empty(0), np.empty((0, 6)), f, frame.start,
                                                     frame.activity_end)
        self.force = ForceErrorScan(frequency=f, window=window)

    @property
    def hinge(self) -> SineSums:
        """The true hinge lengths' sums over the whole steady window: both halves."""
        return self.first.merged(self.second)

    def _in(self, t: np.ndarray) -> np.ndarray:
        """The samples in the streamed span and the steady window."""
        lo, hi = self.span
        t0, t1 = self.frame.window
        return (t > lo) & (t < hi) & (t >= t0) & (t <= t1)

    def true_states(self, t, columns: dict) -> None:
        """The true joint states (ground_truth/joint_states; a log without them: legs/joint_states)."""
        t = np.asarray(t, float)
        position = np.asarray(columns["position"], float)
        lo, hi = self.span
        active = (t > lo) & (t < hi)
        peaks, samples = period_peaks(t[active], position[active, 6:12], self.frame.frequency, self.frame.start,
                                      self.frame.activity_end)
        self.peaks = np.maximum(self.peaks, peaks)
        self.peak_samples += samples
        sel = self._in(t)
        hinge = position[sel, :6] + position[sel, 6:12]
        first = t[sel] < 0.5 * sum(self.frame.window)
        self.first.add(t[sel][first], hinge[first])
        self.second.add(t[sel][~first], hinge[~first])
        self.force.add_measured(t[sel], np.asarray(columns["effort"], float)[sel, :6])

    def sensed_states(self, t, columns: dict) -> None:
        """legs/joint_states: the hinge lengths as the encoders and unit sensors read them."""
        t = np.asarray(t, float)
        sel = self._in(t)
        position = np.asarray(columns["position"], float)[sel]
        self.sensed.add(t[sel], position[:, :6] + position[:, 6:12])

    def true_poses(self, t, poses) -> None:
        """The true platform poses (ground_truth/platform_pose): stamps [n] (s), poses [n, 6] (m, rad)."""
        t = np.asarray(t, float)
        sel = self._in(t)
        self.pose.add(t[sel], np.asarray(poses, float)[sel, :3])

    def pose_estimates(self, t, poses) -> None:
        """platform/pose_estimate: the controller's poses, as true_poses."""
        t = np.asarray(t, float)
        sel = self._in(t)
        self.estimate.add(t[sel], np.asarray(poses, float)[sel, :3])

    def force_estimates(self, t, columns: dict) -> None:
        """legs/force_estimate: stamps [n] (s), {"effort": [n, 6]} (N)."""
        t = np.asarray(t, float)
        sel = self._in(t)
        self.force.add_estimates(t[sel], np.asarray(columns["effort"], float)[sel])

    def sinks(self, true_joints: str, true_pose: str) -> list[dict]:
        """The sinks to read the run with (``load_signals``' ``sinks``, merged with ``merged_sinks``), given the
        topic keys the run's truth is under (``run_signals.truth_key``)."""
        return [{true_joints: self.true_states, true_pose: self.true_poses},
                {"legs/joint_states": self.sensed_states, "platform/pose_estimate": self.pose_estimates,
                 "legs/force_estimate": self.force_estimates}]
