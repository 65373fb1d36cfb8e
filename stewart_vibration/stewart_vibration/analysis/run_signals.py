"""A suite run's signals read from its MCAP (pure: no rclpy): the time series every figure of the run summary
is computed from.

Ground-truth and estimated poses (m, rad; base frame), true and sensed joint states (leg_* lengths and vib_*
displacements in m, efforts in N), leg-force estimates (N), applied and estimated external wrenches (N, N m), the raw
status messages, the nodes' last diagnostics and the /clock values; times are header stamps in sim s (the 500 Hz
streams' stamps, counted for stream health, in ns).
"""

from __future__ import annotations

import functools

import numpy as np

from ..mcap_log.reader import RunFiles, RunReader, open_run
from ..robot import LEG_NAMES, VIB_NAMES, Robot
from .limit_scan import LimitScan
from .run_streams import JOINTS, POSE, STAMP, WRENCH, StreamKind, decode_diagnostics, read_streams, topic_key

# topics a log recorded before the ground truth moved under ground_truth/ (old name -> new name)
LEGACY_TRUTH = {"platform/pose": "ground_truth/platform_pose", "platform/tissue_wrench": "ground_truth/tissue_wrench"}
STREAM_TOPICS = ("legs/joint_states", "ground_truth/platform_pose", "platform/pose_estimate", "legs/force_estimate",
                 "platform/external_wrench_estimate")  # the 500 Hz streams; the first is the input of the rest


# the type each status topic is read as; a log whose status has another type predates it (not read)
TYPED_STATUS = {"vibration/status": "stewart_vibration_interfaces/msg/VibrationUnitsStatus",
                "kinematics/guard_status": "stewart_vibration_interfaces/msg/ForceGuardStatus"}


def load_signals(mcap_path, windows=None, robot: Robot | None = None, sinks: dict | None = None,
                 coverage: bool = True, skip=()) -> dict:
    """Time series of a run (an MCAP file, a run folder: every file in it, in time order; or an open
    RunReader / RunFiles): ground-truth poses, joint states, force estimates (header-stamp times in s), the
    stream counts and the nodes' last diagnostics. Cut files are read as far as their chunks are whole.

    A long run's 500 Hz streams need not be held whole: with ``windows`` they keep only the states in those
    spans (what the vibration figures read), and with ``robot`` the limit check runs over every state as the run
    is read (``limit_scan``). The wrench streams stay whole in a run with an applied tissue wrench (the tissue
    figures read all of them).

    Args:
        mcap_path: an MCAP file or run folder path, or an open RunReader / RunFiles.
        windows: None (every row of every stream), or [(t0, t1)] (s, header stamps): the 500 Hz streams keep
            the rows inside one of them.
        robot: the robot whose limits the states are checked against as they are read ("limit_figures"); None:
            not checked here.
        sinks: {topic key (e.g. "legs/joint_states"): callable} given every decoded batch of the topic as it is
            read (``run_streams.read_streams``): more figures computed as the run streams past.
        coverage: collect the 500 Hz streams' stamps ("stream_stamps", "stream_counts", the files' states: what the
            recording covers); False: empty (the report does not judge coverage, and an hour of them is 72 MB).
        skip: topic keys (as in ``read_streams``, e.g. "platform/pose_estimate") not read: their series come back
            empty (the report draws no estimated pose).

    Returns:
        {"pose": (times [n] (s), poses [n, 6] (m, rad)) the true poses, "joints": (times [n], {"position",
        "velocity", "effort": [n, 12]}, leg_1..6 then vib_1..6) the true joint states (ground_truth/joint_states;
        a log without them: legs/joint_states), "sensed_joints" (legs/joint_states: what the sensors read),
        "pose_estimate" (as "pose": the controller's estimate), "force_estimate": (times [n], {...: [n, 6]}),
        "vibration_starts": distinct vib window stamps (s), "stream_counts" (``counts_in_common_span``),
        "vibration_status" and "guard_status": the raw VibrationUnitsStatus and ForceGuardStatus messages (bytes;
        read with messages.status_values, which counts what is malformed), "untyped_statuses": {topic: count} of
        those recorded in another type (a log from before the typed statuses: left out), "node_diagnostics"
        (``last_diagnostics``), "tissue_wrench" and "wrench_estimate" (times [n] (s), wrenches [n, 6] [force N,
        torque N m]), "clock": the /clock values (s) in recorded order, "stream_stamps": {key of STREAM_TOPICS:
        publish times [n] (ns: the recorded header stamps), file after file}, "files": [{"file", "complete",
        "states": legs/joint_states in it, "first_s", "last_s": its first and last state stamp (s, None without
        states)}] in time order, "undecodable": {topic key: messages that could not be decoded, left out}}.

    Raises:
        McapFileError: a path that is missing, a folder without .mcap files, or a file that is empty or not MCAP.
    """
    reader = mcap_path if isinstance(mcap_path, (RunReader, RunFiles)) else open_run(mcap_path, allow_truncated=True)
    states = StreamKind(JOINTS, tuple(LEG_NAMES + VIB_NAMES))
    kinds = {"ground_truth/joint_states": states, "legs/joint_states": states,
             "legs/force_estimate": StreamKind(JOINTS, tuple(LEG_NAMES), fields=("effort",)),
             **{key: StreamKind(POSE) for key in ("ground_truth/platform_pose", "platform/pose_estimate")},
             **{key: StreamKind(WRENCH) for key in ("ground_truth/tissue_wrench", "platform/external_wrench_estimate")},
             "vibration/joint_trajectory": StreamKind(STAMP), "/clock": StreamKind(STAMP),
             "platform/pose": StreamKind(POSE), "platform/tissue_wrench": StreamKind(WRENCH)}  # LEGACY_TRUTH's
    parts = reader.files if isinstance(reader, RunFiles) else [reader]
    recorded = recorded_keys(reader, kinds)
    keep = {} if windows is None else _window_keep(windows, recorded)
    scan, feeds = None, [dict(sinks or {})]
    if robot is not None:
        scan = LimitScan(robot)
        feeds.append({truth_key(recorded, "ground_truth/joint_states", "legs/joint_states"): scan.add_states,
                      truth_key(recorded, "ground_truth/platform_pose", "platform/pose"): scan.add_poses})
    streams, per_file = read_streams(parts, kinds, raw=("vibration/status", "kinematics/guard_status", "/diagnostics"),
                                     counted=STREAM_TOPICS if coverage else (), sinks=merged_sinks(feeds), keep=keep,
                                     skip=skip)
    got = streams.decoded
    for old, new in LEGACY_TRUTH.items():  # a log from before the truth had its own topics
        if not got[new][0].size:
            got[new] = got[old]
    typed: dict[str, list[bytes]] = {"vibration/status": [], "kinematics/guard_status": []}
    untyped: dict[str, int] = {}
    for key, bucket in typed.items():  # read field by field later: a spoofed status is counted
        for type_name, data in streams.raw[key]:
            if type_name == TYPED_STATUS[key]:
                bucket.append(data)
            else:  # a log from before the typed statuses (DiagnosticStatus): not read as one of them
                untyped[key] = untyped.get(key, 0) + 1
    diagnostics, bad_diagnostics = decode_diagnostics([data for _type, data in streams.raw["/diagnostics"]])
    undecodable = dict(streams.undecodable)
    if bad_diagnostics:
        undecodable["/diagnostics"] = bad_diagnostics
    stamps = streams.publish_ns
    sensed = got["legs/joint_states"]
    return {
        "pose": got["ground_truth/platform_pose"],
        "joints": got["ground_truth/joint_states"] if got["ground_truth/joint_states"][0].size else sensed,
        "sensed_joints": sensed,
        "pose_estimate": got["platform/pose_estimate"],
        "force_estimate": got["legs/force_estimate"],
        "vibration_starts": np.unique(got["vibration/joint_trajectory"]),
        "stream_counts": counts_in_common_span(stamps),
        "vibration_status": typed["vibration/status"],
        "node_diagnostics": last_diagnostics(diagnostics),
        "tissue_wrench": got["ground_truth/tissue_wrench"],
        "wrench_estimate": got["platform/external_wrench_estimate"],
        "guard_status": typed["kinematics/guard_status"],
        "untyped_statuses": untyped,
        "undecodable": undecodable,
        "clock": got["/clock"],
        "stream_stamps": stamps,
        "files": [_file_coverage(f) for f in per_file],
        **({"limit_figures": scan.figures(got["/clock"])} if scan is not None else {}),
    }


WINDOWED = ("ground_truth/joint_states", "legs/joint_states", "legs/force_estimate", "ground_truth/platform_pose",
            "platform/pose_estimate", "platform/pose")  # the 500 Hz streams a long run need not hold whole
TISSUE_KEYS = ("ground_truth/tissue_wrench", "platform/tissue_wrench")  # the applied tissue wrench (and its old name)
WRENCHES = (*TISSUE_KEYS, "platform/external_wrench_estimate")


def truth_key(recorded: set[str], truth: str, fallback: str) -> str:
    """The topic key a figure of the truth reads: ``truth``, or ``fallback`` in a log without it (the joints:
    the sensed states of a log from before the truth had its own topics; the pose: its old name)."""
    return truth if truth in recorded else fallback


def merged_sinks(feeds: list[dict]) -> dict:
    """{key: callable}: every callable the ``feeds`` ({key: callable} each) give for a key, called in turn."""
    out: dict = {}
    for feed in feeds:
        for key, sink in feed.items():
            out.setdefault(key, []).append(sink)
    return {key: sinks[0] if len(sinks) == 1 else functools.partial(_each, sinks) for key, sinks in out.items()}


def _each(sinks: list, *batch) -> None:
    for sink in sinks:
        sink(*batch)


def recorded_keys(reader: RunReader | RunFiles, keys) -> set[str]:
    """The topic ``keys`` that some file of a run (an open RunReader / RunFiles) holds messages of."""
    return {key for t in reader.topics() if t.message_count for key in [topic_key(t.topic, keys)] if key is not None}


def _window_keep(windows, recorded: set[str]) -> dict:
    """{key: mask of the stamps inside one of ``windows``} for the streams held only there (the wrenches too in
    a run without an applied tissue wrench)."""
    spans = np.asarray(list(windows), float).reshape(-1, 2)

    def inside(times: np.ndarray) -> np.ndarray:
        return np.asarray(((times[:, None] >= spans[:, 0]) & (times[:, None] <= spans[:, 1])).any(axis=1), bool)

    tissue = bool(recorded.intersection(TISSUE_KEYS))
    return {key: inside for key in WINDOWED + (() if tissue else WRENCHES)}


def _file_coverage(part: dict) -> dict:
    """What one file holds: its name, whether it is complete, its states and their first and last stamp (s)."""
    mine = part["publish_ns"].get("legs/joint_states", np.empty(0, np.int64))
    first, last = (int(mine.min()) / 1e9, int(mine.max()) / 1e9) if mine.size else (None, None)
    return {"file": part["file"], "complete": part["complete"], "states": int(mine.size), "first_s": first,
            "last_s": last}


def counts_in_common_span(stamps: dict) -> dict:
    """Messages per 500 Hz topic whose stamps lie in the span every one of them covers (from the last
    first stamp to the first last stamp: start-up and shut-down are not losses).

    Args:
        stamps: {key of STREAM_TOPICS: stamps [n] (ns)} (``load_signals``' stream_stamps).

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
        arrays: the status lists of DiagnosticArray messages (``messages.diagnostic_status.DiagnosticStatusData``), in
            time order.

    Returns:
        {status name: (level as int, message, {key: value})}.
    """
    out = {}
    for statuses in arrays:
        for status in statuses:
            out[status.name] = (int(status.level), status.message, dict(status.values))
    return out
