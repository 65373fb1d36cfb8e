"""A suite run's signals read from its MCAP (pure: no rclpy): the time series every figure of the run summary
is computed from.

Ground-truth and estimated poses (m, rad; base frame), true and sensed joint states (leg_* lengths and vib_*
displacements in m, efforts in N), leg-force estimates (N), applied and estimated external wrenches (N, N m), the raw
status messages, the nodes' last diagnostics and the /clock values; times are header stamps in sim s (the 500 Hz
streams' stamps, counted for stream health, in ns).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..mcap_log.reader import RunFiles, RunReader, open_run
from ..messages.arrays import joint_arrays, pose_array, stamp_s
from ..robot import LEG_NAMES

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
