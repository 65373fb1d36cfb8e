"""The 500 Hz streams the planning page plots (pure): raw messages queued as they come, decoded in batches at
each frame into the full-rate buffers of the run summary, the decimated plot rows and the latest values.

Streams, by topic: legs/joint_states (leg_i strut lengths m and vib_i unit displacements m as positions, the
measured axial forces N as efforts), platform/pose_estimate (the controller's pose [x, y, z, roll, pitch,
yaw], m and rad, of the platform frame in the base frame), legs/force_estimate (the estimated axial forces N as
efforts). Stamps are s of the messages' clock (sim time); ``now`` s of the node's monotonic clock.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import MalformedMessageError, StewartError
from ..messages.joint_states import JointStateDecoder, decode_joint_states_dropping_malformed
from ..messages.stamped import poses_from_cdr
from .model import Decimator, StreamBuffer

JOINTS, POSES, FORCES = "legs/joint_states", "platform/pose_estimate", "legs/force_estimate"
STREAM_RATE_HZ = 500.0
ESTIMATE_FRESH_S = 1.0  # a pose estimate older than this is no start pose for a preview or a vibration
STREAMS_IDLE_S = 5.0  # the 500 Hz subscriptions are dropped this long after the last page closed
SUBSCRIBE, DROP = "subscribe", "drop"

Refuse = Callable[..., None]  # refuse(topic, error, count=1): count malformed messages of topic


@dataclass
class RunBuffers:
    """The last seconds of the full-rate streams a run summary reads: joints rows [n, 24] (positions leg_1..6,
    vib_1..6 m; efforts leg_1..6, vib_1..6 N), poses [n, 6] (m, rad), forces [n, 6] (N)."""

    joints: StreamBuffer
    poses: StreamBuffer
    forces: StreamBuffer


class LiveStreams:
    """The three streams between frames. ``columns(names)``: the (leg, vib) column indices of a JointState's
    names (nodes.message_conversions.JointColumns); ``refuse``: how malformed messages are counted."""

    def __init__(self, keep_s: float, plot_rate_hz: float, columns: Callable, refuse: Refuse):
        self.columns, self.refuse = columns, refuse
        self.raw: dict[str, list[bytes]] = {JOINTS: [], POSES: [], FORCES: []}
        self.seen: dict[str, float] = {}  # topic -> monotonic s it was last received (the page's ages)
        self.decoders = {JOINTS: JointStateDecoder(), FORCES: JointStateDecoder()}
        every = max(1, round(STREAM_RATE_HZ / plot_rate_hz))
        self.decimators = {JOINTS: Decimator(every), FORCES: Decimator(every)}
        self.buffers = RunBuffers(StreamBuffer(keep_s), StreamBuffer(keep_s), StreamBuffer(keep_s))
        self.latest_joints: tuple[float, np.ndarray] | None = None  # stamp, the newest joints row [24]
        self.latest_estimate: tuple[float, np.ndarray] | None = None  # stamp, the newest pose estimate [6]
        self.plots: dict[str, list] = {"joints": [], "forces": []}  # decimated rows since the last frame

    def receive(self, topic: str, data: bytes) -> None:
        """A raw message of ``topic`` (decoded at the next ``drain``)."""
        self.raw[topic].append(data)

    def drain(self, now: float) -> tuple[np.ndarray, np.ndarray]:
        """Decode what came since the last call; returns the new pose estimates: stamps [n] (s), poses [n, 6]."""
        messages = {topic: raw for topic, raw in self.raw.items() if raw}
        self.raw = {JOINTS: [], POSES: [], FORCES: []}
        for topic in messages:
            self.seen[topic] = now
        if JOINTS in messages:
            self._decode_joints(messages[JOINTS])
        if FORCES in messages:
            self._decode_forces(messages[FORCES])
        return self._decode_poses(messages.get(POSES, []))

    def _batches(self, topic: str, messages: list[bytes]):
        return decode_joint_states_dropping_malformed(
            messages, self.decoders[topic], lambda reason: self.refuse(topic, MalformedMessageError(reason)))[0]

    def _decode_joints(self, messages: list[bytes]) -> None:
        for batch in self._batches(JOINTS, messages):
            legs, vib = self.columns(batch.names)
            if legs is None or vib is None:
                self.refuse(JOINTS, MalformedMessageError(
                    f"names {list(batch.names)[:14]} lack a leg_* or vib_* or repeat one", field="name",
                    kind="names"), len(batch.stamps))
                continue
            cols = np.concatenate([legs, vib])
            rows = np.concatenate([batch.position[:, cols], batch.effort[:, cols]], axis=1)
            self.buffers.joints.add(batch.stamps, rows)
            self.latest_joints = (batch.stamps[-1], rows[-1])
            for i in self.decimators[JOINTS].take(len(batch.stamps)):  # t, vib_1..6 (um), leg_1..6 force (N)
                self.plots["joints"].append([batch.stamps[i], *(rows[i, 6:12] * 1e6), *rows[i, 12:18]])

    def _decode_forces(self, messages: list[bytes]) -> None:
        for batch in self._batches(FORCES, messages):
            legs, _ = self.columns(batch.names)
            if legs is None:
                self.refuse(FORCES, MalformedMessageError(
                    f"names {list(batch.names)[:14]} lack a leg_* or repeat one", field="name", kind="names"),
                    len(batch.stamps))
                continue
            effort = batch.effort[:, legs]
            self.buffers.forces.add(batch.stamps, effort)
            for i in self.decimators[FORCES].take(len(batch.stamps)):
                self.plots["forces"].append([batch.stamps[i], *effort[i]])

    def _decode_poses(self, messages: list[bytes]) -> tuple[np.ndarray, np.ndarray]:
        if not messages:
            return np.empty(0), np.empty((0, 6))
        batch = poses_from_cdr(messages, "pose estimate")
        for error in batch.errors:
            self.refuse(POSES, error)
        if not len(batch.kept):
            return np.empty(0), np.empty((0, 6))
        self.buffers.poses.add(batch.stamps, batch.values)
        self.latest_estimate = (batch.stamps[-1], batch.values[-1])
        return batch.stamps, batch.values

    def take_plots(self) -> dict[str, list]:
        """The plot rows since the last call (each stream's rows once)."""
        plots, self.plots = self.plots, {"joints": [], "forces": []}
        return plots

    def estimate(self, now: float) -> np.ndarray:
        """The latest pose estimate [6] (m, rad); StewartError if none came in the last ESTIMATE_FRESH_S."""
        if self.latest_estimate is None or now - self.seen.get(POSES, 0) > ESTIMATE_FRESH_S:
            raise StewartError("no recent platform/pose_estimate (is the kinematics node running?)")
        return self.latest_estimate[1]


@dataclass
class StreamWatch:
    """When to hold the 500 Hz subscriptions: while ``watched`` (a page is open, or a move or vibration it
    started is followed) and for ``idle_s`` after; nobody watching costs the suite nothing."""

    unwatched_since: float  # monotonic s
    idle_s: float = STREAMS_IDLE_S

    def step(self, now: float, watched: bool, subscribed: bool) -> str | None:
        """SUBSCRIBE, DROP or None (as they are) at ``now`` (s)."""
        if watched:
            self.unwatched_since = now
            return None if subscribed else SUBSCRIBE
        return DROP if subscribed and now - self.unwatched_since > self.idle_s else None
