"""mcap_recorder: record the suite's topics as serialized CDR to a rosbag2-compatible MCAP.

Raw subscriptions with the QoS the publishers offer (rosbag2's rule: reliable /
transient_local only when every publisher offers it), created as soon as a
topic appears on the graph. log_time = receive time on the node clock (sim
time with use_sim_time); publish_time = header.stamp when the type starts with
a std_msgs/Header, else log_time. A writer thread does all MCAP work
(stewart_vibration.mcap_log.writer), so callbacks only enqueue.

Parameters: output_dir (str, "runs"), file_pattern (str, "run_{stamp}.mcap";
fields {stamp} local time YYYYmmdd_HHMMSS, {node}), record_on_start (bool,
true), topics (str[], empty = DESIGN.md topics relative to the namespace plus
/clock, /diagnostics, /rosout), qos_depth (int, 3000), chunk_size (bytes,
262144), flush_period_s (s, 0.5), discovery_period_s (s, 0.2).
Services: ~/start, ~/stop (std_srvs/Trigger; message = file path).
SIGINT/SIGTERM (also during start-up): the file is finished (summary, metadata.yaml) before exit.

Bag directory: ``output_dir`` is a rosbag2 bag directory. When a recording
finishes, the recorder writes ``output_dir/metadata.yaml`` (rosbag2 version 9,
as ``ros2 bag record`` does) listing the files this recorder process wrote
there (one per ~/start..~/stop, like rosbag2's splits), so ``ros2 bag
info/play output_dir`` and ``rosbags.rosbag2.Reader(output_dir)`` open it.
While a file is being written the folder has no metadata.yaml (a
metadata.yaml left by an earlier recording is removed when a recording starts;
that recording's .mcap stays in the folder, unlisted). After a crash
(SIGKILL) the folder has none until ``stewart-vibration mcap-recover`` rebuilds
the cut file and writes one. Other files in the folder (logs/, report/,
summary.json) are ignored by bag readers.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import rclpy
from rcl_interfaces.msg import IntegerRange, ParameterDescriptor
from rclpy.clock import Clock, ClockType
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from std_srvs.srv import Trigger

from ..mcap_log.bag_metadata import BagFile, bag_metadata, remove_metadata_yaml, write_metadata_yaml
from ..mcap_log.qos_yaml import dump_qos_profiles, request_for_offers
from ..mcap_log.writer import McapRunWriter
from .common import (
    OK,
    STREAM_DEPTH,
    WARN,
    Diagnostics,
    StopFlag,
    declare_float,
    declare_read_only,
    float_param,
    make_executor,
    spin_until_stopped,
)
from .ros_graph import message_class, offered_profile, rclpy_profile

SUITE_TOPICS = [
    "platform/target_pose",
    "legs/joint_trajectory",
    "vibration/joint_trajectory",
    "legs/joint_states",
    "platform/pose",
    "platform/pose_estimate",
    "legs/force_estimate",
    "platform/external_wrench_estimate",
    "platform/tissue_wrench",
    "kinematics/guard_status",
    "vibration/status",
    "robot_markers",
    "/clock",
    "/diagnostics",
    "/rosout",
]


class McapRecorderNode(Node):
    """Discovers the wanted topics, subscribes raw, hands bytes to an McapRunWriter."""

    def __init__(self, **kwargs):
        super().__init__("mcap_recorder", **kwargs)
        # output_dir, file_pattern, chunk_size and flush_period_s apply to the next file (live); the others
        # are read once at start (read-only: ros2 param set says so)
        self.declare_parameter("output_dir", "runs", ParameterDescriptor(description="folder of the next file"))
        self.declare_parameter("file_pattern", "run_{stamp}.mcap", ParameterDescriptor(
            description="name of the next file ({stamp}: local time, {node})"))
        declare_read_only(self, "record_on_start", True, "open a file at start (else on ~/start)")
        declare_read_only(self, "topics", [""], "topics to record (empty = the suite's)")
        declare_read_only(self, "qos_depth", STREAM_DEPTH, "history depth of the recording subscriptions (6 s, 500 Hz)")
        self.declare_parameter("chunk_size", 256 * 1024, ParameterDescriptor(
            description="MCAP chunk size of the next file, bytes", integer_range=[
                IntegerRange(from_value=1024, to_value=64 * 1024 * 1024, step=1)]))
        declare_float(self, "flush_period_s", 0.5, float_param(
            "a chunk is written at least this often (crash safety), s; next file", 0.01, 60.0))
        declare_float(self, "discovery_period_s", 0.2, float_param(
            "topic discovery period, s (read at start)", 0.01, 10.0, read_only=True))
        names = [t for t in self.get_parameter("topics").value if t] or SUITE_TOPICS
        self._wanted = {self.resolve_topic_name(t) for t in names}
        self._known: dict[str, tuple[str, str, str]] = {}  # topic -> (type, qos yaml, hash)
        self._subs = {}
        self._writer: McapRunWriter | None = None
        self._bag_files: dict[Path, list[BagFile]] = {}  # folder -> files this process finished there
        self._clock = self.get_clock()
        self.create_service(Trigger, "~/start", self._on_start)
        self.create_service(Trigger, "~/stop", self._on_stop)
        self.create_timer(float(self.get_parameter("discovery_period_s").value), self._discover)
        # the file being written and its counters, for UIs that start after the "recording to" log line
        self.diagnostics = Diagnostics(self, "mcap recorder")
        self.create_timer(1.0, self.report, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self._last_file = ""
        self._discover()
        if self.get_parameter("record_on_start").value:
            self.start_recording()
        self.report()

    def report(self) -> None:
        """/diagnostics: recording <path> (OK) or not recording, with the counters; WARN once messages dropped."""
        writer = self._writer
        if writer is None:
            self.diagnostics.set(OK, "not recording", path="", last_file=self._last_file)
            return
        stats = writer.stats
        level = WARN if stats.dropped else OK
        message = f"recording {writer.path}" + (f"; {stats.dropped} messages dropped" if stats.dropped else "")
        self.diagnostics.set(level, message, path=str(writer.path), last_file=self._last_file,
                             received=stats.received, written=stats.written, dropped=stats.dropped,
                             topics=len(self._known))

    # -- recording ------------------------------------------------------------------
    def _next_path(self) -> Path:
        pattern = str(self.get_parameter("file_pattern").value)
        name = pattern.format(stamp=time.strftime("%Y%m%d_%H%M%S"), node=self.get_name())
        path = Path(str(self.get_parameter("output_dir").value)) / name
        n = 1
        while path.exists():
            path = path.with_name(f"{Path(name).stem}_{n}{Path(name).suffix}")
            n += 1
        return path

    def start_recording(self) -> Path:
        """Open a new file (if not recording) and declare every topic already subscribed."""
        if self._writer is None:
            path = self._next_path()
            path.parent.mkdir(parents=True, exist_ok=True)
            if remove_metadata_yaml(path.parent) and path.parent.resolve() not in self._bag_files:
                self.get_logger().info(
                    f"removed the metadata.yaml of an earlier recording in {path.parent}: the folder now holds "
                    "this recording's bag (earlier .mcap files stay there, unlisted)")
            writer = McapRunWriter(
                path,
                chunk_size=int(self.get_parameter("chunk_size").value),
                flush_period_s=float(self.get_parameter("flush_period_s").value),
            )
            for topic, (type_name, qos_yaml, type_hash) in self._known.items():
                writer.add_topic(topic, type_name, qos_yaml, type_hash)
            self._writer = writer
            self.get_logger().info(f"recording to {writer.path}")
            self.report()
        return self._writer.path

    def stop_recording(self) -> dict | None:
        """Finish the file (summary, indexes, rosbag2 metadata); returns the counters."""
        writer, self._writer = self._writer, None
        if writer is None:
            return None
        stats = writer.close()
        folder = writer.path.parent.resolve()
        files = self._bag_files.setdefault(folder, [])
        files.append(writer.bag_file())
        metadata = write_metadata_yaml(folder, bag_metadata(files))
        self.get_logger().info(f"finished {writer.path}; {metadata} lists {len(files)} file(s)")
        self._last_file = str(writer.path)
        self.report()
        report = {
            "path": str(writer.path),
            "metadata_yaml": str(metadata),
            "received": stats.received,
            "written": stats.written,
            "dropped": stats.dropped,
            "max_backlog": stats.max_backlog,
            "per_topic": dict(stats.per_topic),
        }
        # One machine-readable line for tests and the benchmark.
        print("MCAP_RECORDER_STATS " + json.dumps(report), flush=True)
        return report

    def _on_start(self, _req, resp):
        path = self.start_recording()
        resp.success, resp.message = True, str(path)
        return resp

    def _on_stop(self, _req, resp):
        report = self.stop_recording()
        resp.success = report is not None
        resp.message = report["path"] if report else "not recording"
        return resp

    # -- discovery ------------------------------------------------------------------
    def _discover(self) -> None:
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
        clock = self._clock

        def on_message(data: bytes, _topic=topic) -> None:
            writer = self._writer
            if writer is not None:
                writer.submit(_topic, clock.now().nanoseconds, data)

        self._subs[topic] = self.create_subscription(
            message_class(type_name), topic, on_message, rclpy_profile(request), raw=True
        )
        self.get_logger().info(f"subscribed {topic} [{type_name}] {request.reliability}")


def main(args=None) -> int:
    """Run the mcap_recorder node until SIGINT / SIGTERM, then finish the MCAP file; returns 0."""
    rclpy.init(args=args)
    stop = StopFlag().install()  # a flag only: a stop during start-up still finishes cleanly
    node = McapRecorderNode()
    executor = make_executor()
    executor.add_node(node)
    try:
        spin_until_stopped(executor, stop)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.stop_recording()
        executor.remove_node(node)
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
