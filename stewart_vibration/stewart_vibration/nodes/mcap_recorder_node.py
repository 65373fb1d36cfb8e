"""mcap_recorder: record the suite's topics as serialized CDR to a rosbag2-compatible MCAP.

Raw subscriptions with the QoS the publishers offer (rosbag2's rule: reliable / transient_local only when every
publisher offers it), created as soon as a topic appears on the graph. log_time = receive time on the node clock
(sim time with use_sim_time); publish_time = header.stamp when the type starts with a std_msgs/Header, else
log_time. A writer thread does all MCAP work (mcap_log.writer), so callbacks only enqueue.

Parameters (parameters/tables.py, docs/parameters.md): output_dir ("": a run folder of its own under runs/),
file_pattern, record_on_start, topics (empty: the suite's, plus /clock, /diagnostics, /rosout), qos_depth,
chunk_size, flush_period_s, discovery_period_s. A bad output_dir or file_pattern is refused with the reason: at
start (one line, exit code 2) and by ``ros2 param set``.
Services: ~/start (StartRecording: a new file, optionally named; the outcome and the file's path), ~/stop
(StopRecording: the outcome, the finished file's path, its message and byte counts; NOT_RECORDING when there
is none, RECORDING_FAILED when its write failed).
SIGINT/SIGTERM (also during start-up): the file is finished (summary, metadata.yaml) before exit.

Faults it reports at once on /diagnostics (ERROR, with ``fault`` = write_failed, ``fault_code`` = the errno name
and ``fault_reason``): a failed write (a full disk, an I/O error) or a file that lost its name (its folder
removed). The recording stops there, the file keeps every whole chunk written before (``mcap-recover`` rebuilds
its summary) and is not listed in metadata.yaml. Samples lost before they reached the recorder are counted from
the gaps in the publication sequence numbers of topics with one publisher (``lost``, ``sequence_gaps``, WARN)
when the node runs the single-threaded executor (STEWART_EXECUTOR=single: rclpy 7.1's EventsExecutor cannot hand
a callback the message info). The recorder arms no DDS "message lost" event: in the rmw_fastrtps of these wheels,
taking that event while DDS reports a loss locks two mutexes in opposite orders, and under real loss the recorder
deadlocked (stopped recording, ignored SIGINT). The run summary finds lost samples in the recording itself either
way (gaps in every 500 Hz stream's stamps and in /clock).

Bag directory: ``output_dir`` is a rosbag2 bag directory with a metadata.yaml listing the files finished there
(``ros2 bag info/play`` open it); see mcap_log.bag_folders.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.node import Node

from stewart_vibration_interfaces.srv import StartRecording, StopRecording

from ..errors import InvalidInputError
from ..mcap_log.bag_folders import BagFolders
from ..mcap_log.output_paths import bag_folder, check_file_pattern
from ..mcap_log.qos_yaml import dump_qos_profiles, request_for_offers
from ..mcap_log.recording_status import finished_report, recording_status
from ..mcap_log.writer import McapRunWriter
from ..messages.fields import check_text
from ..messages.status_values import MAX_PATH
from ..messages.stream_health import SequenceGaps
from ..parameters.tables import MCAP_RECORDER
from ..runtime.run_folders import new_run_folder
from .diagnostics import ERROR, OK, WARN, Diagnostics
from .node_parameters import declare_table
from .outcomes import outcome
from .ros_graph import message_class, offered_profile, rclpy_profile
from .run_loop import run_node

SUITE_TOPICS = [  # the suite's topics (docs/interfaces.md), relative to the namespace, and the global ones
    "legs/trajectory_status", "legs/joint_trajectory", "vibration/joint_trajectory", "legs/joint_states",
    "platform/imu", "platform/tracker_pose", "ground_truth/joint_states", "ground_truth/platform_pose",
    "platform/pose_estimate", "legs/force_estimate", "platform/external_wrench_estimate",
    "ground_truth/tissue_wrench", "kinematics/guard_status", "kinematics/calibration_samples", "vibration/status",
    "robot_markers", "/clock", "/diagnostics", "/rosout",
]
RUNS_ROOT = "runs"  # where output_dir "" makes the recorder's own run folder (under the working directory)
FAULT_CHECK_PERIOD_S = 0.1  # how often the writer thread's failure is looked for (wall s)


class McapRecorderNode(Node):
    """Discovers the wanted topics, subscribes raw, hands bytes to an McapRunWriter."""

    def __init__(self, **kwargs):
        super().__init__("mcap_recorder", **kwargs)
        # output_dir, file_pattern, chunk_size and flush_period_s apply to the next file (live); the others
        # are read once at start (read-only: ros2 param set says so)
        declare_table(self, MCAP_RECORDER)
        self._cwd = Path.cwd()
        check_file_pattern(str(self.get_parameter("file_pattern").value))
        self._check_output_dir(str(self.get_parameter("output_dir").value))
        self.add_on_set_parameters_callback(self._on_set_parameters)
        names = [t for t in self.get_parameter("topics").value if t] or SUITE_TOPICS
        self._wanted = {self.resolve_topic_name(t) for t in names}
        self._known: dict[str, tuple[str, str, str]] = {}  # topic -> (type, qos yaml, hash)
        self._subs = {}
        self._writer: McapRunWriter | None = None
        self.bags = BagFolders(self._cwd, lambda: new_run_folder(self._cwd / RUNS_ROOT))
        self._clock = self.get_clock()
        # message info (publication sequence numbers) reaches callbacks only with the single-threaded executor
        self._gaps = SequenceGaps() if os.environ.get("STEWART_EXECUTOR") == "single" else None
        self._single_publisher: set[str] = set()  # topics with one publisher (sequence numbers are per publisher)
        self._fault: tuple[str, str] | None = None  # (errno name, reason) of the last write failure
        self.create_service(StartRecording, "~/start", self._on_start)
        self.create_service(StopRecording, "~/stop", self._on_stop)
        # discovery runs on the steady clock: a recorder that waited for sim time would record nothing while
        # /clock is silent or not yet matched (a recorder respawned beside a running suite)
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(float(self.get_parameter("discovery_period_s").value), self._discover, clock=steady)
        # the file being written and its counters, for UIs that start after the "recording to" log line
        self.diagnostics = Diagnostics(self, "mcap recorder")
        self.create_timer(1.0, self.report, clock=steady)
        self.create_timer(FAULT_CHECK_PERIOD_S, self._check_writer, clock=steady)
        self._last_file = ""
        self._discover()
        if self.get_parameter("record_on_start").value:
            self.start_recording()
        self.report()

    # -- parameters -------------------------------------------------------------------
    def _check_output_dir(self, output_dir: str) -> None:
        if output_dir:
            bag_folder(output_dir, self._cwd)

    def _on_set_parameters(self, params) -> SetParametersResult:
        for param in params:
            try:
                if param.name == "file_pattern":
                    check_file_pattern(str(param.value))
                elif param.name == "output_dir":
                    self._check_output_dir(str(param.value))
            except InvalidInputError as exc:
                return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def report(self) -> None:
        """/diagnostics: the recording, its counters and its fault (mcap_log.recording_status)."""
        writer = self._writer
        severity, message, values = recording_status(writer.path if writer else None,
                                                     writer.stats if writer else None, self._fault, self._gaps)
        self.diagnostics.set({"ok": OK, "warn": WARN, "error": ERROR}[severity], message, last_file=self._last_file,
                             topics=len(self._known), **values)

    def _check_writer(self) -> None:
        """A failed write is reported the moment the writer thread has seen it (ERROR, logged once)."""
        writer = self._writer
        if writer is None or writer.failure is None or self._fault is not None:
            return
        failure = writer.failure
        self._fault = (failure.code, failure.reason)
        self.get_logger().error(f"recording stopped: {failure.reason}; {writer.path} keeps its first "
                                f"{failure.good_bytes:,} bytes (whole chunks; rebuild its summary with "
                                f"stewart-vibration mcap-recover {writer.path})")
        self.report()

    # -- recording ------------------------------------------------------------------
    def start_recording(self, name: str = "") -> Path:
        """Open a new file (if not recording; ``name``: its stem, "" = file_pattern) and declare every topic
        already subscribed.

        Raises:
            InvalidInputError: output_dir or file_pattern is refused (``mcap_log.output_paths``).
            OSError: the folder or the file cannot be created.
        """
        if self._writer is None:
            folder = self.bags.folder(str(self.get_parameter("output_dir").value))
            pattern = f"{name}.mcap" if name else str(self.get_parameter("file_pattern").value)
            path = self.bags.next_path(folder, pattern, self.get_name())
            adopted = self.bags.take_over(folder)
            if adopted is not None:
                self.get_logger().info(f"{folder} holds an earlier recording: its {adopted} file(s) stay listed in "
                                       "its metadata.yaml beside the new ones")
            writer = McapRunWriter(
                path,
                chunk_size=int(self.get_parameter("chunk_size").value),
                flush_period_s=float(self.get_parameter("flush_period_s").value),
            )
            for topic, (type_name, qos_yaml, type_hash) in self._known.items():
                writer.add_topic(topic, type_name, qos_yaml, type_hash)
            self._writer = writer
            self._fault = None
            self.get_logger().info(f"recording to {writer.path}")
            self.report()
        return self._writer.path

    def stop_recording(self) -> dict | None:
        """Finish the file (summary, indexes, rosbag2 metadata); returns the counters. A file whose write
        failed is closed as it was cut and left out of metadata.yaml."""
        writer, self._writer = self._writer, None
        if writer is None:
            return None
        stats = writer.close()
        failure = writer.failure
        if failure is not None:
            self._fault = (failure.code, failure.reason)
        metadata = None
        try:
            metadata, listed = self.bags.finish(writer.path.parent, writer.bag_file() if failure is None else None)
            self.get_logger().info(f"finished {writer.path}; {metadata} lists {listed} file(s)")
        except OSError as exc:
            self.get_logger().error(f"finished {writer.path}, but its metadata.yaml cannot be written: {exc}")
        if failure is not None:
            self.get_logger().error(f"{writer.path} is cut at {failure.good_bytes:,} bytes ({failure.reason}); "
                                    f"rebuild it with: stewart-vibration mcap-recover {writer.path}")
        self._last_file = str(writer.path)
        self.report()
        report = finished_report(writer.path, stats, failure, self._gaps, self._clock.now().nanoseconds * 1e-9,
                                 metadata)
        # One machine-readable line for tests, the bring-up and the benchmark. The log may be on the disk that is
        # full: a failed print must not take the recorder (and the file it finishes) down.
        try:
            print("MCAP_RECORDER_STATS " + json.dumps(report), flush=True)
        except OSError as exc:
            self.get_logger().error(f"cannot write the recorder's counts to its log: {exc}")
        return report

    def shutdown(self) -> None:
        """SIGINT / SIGTERM: finish the file."""
        self.stop_recording()

    def _on_start(self, request, response):
        if self._writer is not None:
            response.outcome = outcome("BUSY", f"already recording to {self._writer.path}: stop it first")
            response.path = str(self._writer.path)
            return response
        try:
            check_text(request.name, "name", MAX_PATH)
            path = self.start_recording(request.name)
        except (InvalidInputError, OSError) as exc:
            message = f"cannot start a recording: {exc}"
            response.outcome = outcome("INVALID_ARGUMENT" if isinstance(exc, InvalidInputError) else
                                       "RECORDING_FAILED", message)
            self.get_logger().error(message)
            return response
        response.outcome, response.path = outcome("SUCCEEDED", f"recording to {path}"), str(path)
        return response

    def _on_stop(self, _request, response):
        report = self.stop_recording()
        if report is None:
            response.outcome = outcome("NOT_RECORDING", "not recording: nothing to stop")
            return response
        response.path, response.messages = report["path"], int(report["written"])
        response.bytes = Path(report["path"]).stat().st_size if Path(report["path"]).exists() else 0
        if report["failure"]:
            response.outcome = outcome("RECORDING_FAILED", f"{report['path']}: recording failed: "
                                       f"{report['failure']['reason']}")
        else:
            response.outcome = outcome("SUCCEEDED", f"finished {report['path']}")
        return response

    # -- discovery ------------------------------------------------------------------
    def _discover(self) -> None:
        if self._gaps is not None:
            single = {t for t in self._subs if self.count_publishers(t) == 1}
            self._single_publisher.intersection_update(single)  # in place: the callbacks hold this set
            self._single_publisher.update(single)
        missing = self._wanted - self._subs.keys()
        if not missing:
            return
        for topic, types in self.get_topic_names_and_types():
            if topic not in missing or len(types) != 1:
                continue
            infos = self.get_publishers_info_by_topic(topic)
            if not infos:
                continue
            try:
                self._subscribe(topic, types[0], infos)
            except Exception as exc:  # noqa: BLE001 - unknown type: keep recording the rest
                self.get_logger().error(f"cannot record {topic} ({types[0]}): {exc}")
                self._wanted.discard(topic)

    def _subscribe(self, topic: str, type_name: str, infos) -> None:
        offers = [offered_profile(i.qos_profile) for i in infos]
        request = request_for_offers(offers, int(self.get_parameter("qos_depth").value))
        type_hash = str(infos[0].topic_type_hash)
        self._known[topic] = (type_name, dump_qos_profiles(offers), type_hash)
        if self._writer is not None:
            self._writer.add_topic(topic, type_name, *self._known[topic][1:])
        clock, gaps, single = self._clock, self._gaps, self._single_publisher

        if gaps is None:
            def on_message(data: bytes, _topic=topic) -> None:
                writer = self._writer
                if writer is not None:
                    writer.submit(_topic, clock.now().nanoseconds, data)
        else:
            def on_message(data: bytes, info, _topic=topic) -> None:  # type: ignore[misc]
                writer = self._writer
                if writer is not None:
                    writer.submit(_topic, clock.now().nanoseconds, data)
                if _topic in single:
                    gaps.seen(_topic, info.get("publication_sequence_number"))

        self._subs[topic] = self.create_subscription(
            message_class(type_name), topic, on_message, rclpy_profile(request), raw=True)
        self.get_logger().info(f"subscribed {topic} [{type_name}] {request.reliability}")


def main(args=None) -> int:
    """Run the mcap_recorder node until SIGINT / SIGTERM, then finish the MCAP file; returns 0 (2: it cannot
    start, e.g. a refused output_dir or file_pattern, said in one line)."""
    return run_node(McapRecorderNode, args)


if __name__ == "__main__":
    sys.exit(main())
