"""mcap_replay: republish a recorded MCAP run with its original timing.

The recorded CDR bytes are published as they are (Publisher.publish(bytes), no
re-serialisation), each topic with the QoS its publishers offered in the
recording. Message k is published at (log_time_k - t0) / rate after the start.

Parameters (read once at start, so read-only; numbers accept integers):
path (str: a .mcap or a run folder / rosbag2 bag directory), rate (1.0, > 0),
start_offset_s (0.0, s into the run), loop (false), publish_clock (false:
the recorded /clock, if any, is replayed as recorded; true: the node publishes
/clock itself at clock_rate_hz and the recorded /clock is not replayed),
clock_rate_hz (100.0 wall Hz; 0 = the rate of the recorded /clock, 100 Hz if
none), topics (str[], empty = all), exclude_topics (str[]),
wait_for_subscribers_s (0.0: wait up to this long for every replay publisher
to be matched by every subscriber the ROS graph shows on its topic, and then
for the counts to stay unchanged for SUBSCRIBERS_SETTLE_S, before starting), exit_when_done (true).

A missing, empty, non-MCAP or truncated file, or a bad parameter, is one
``mcap_replay: error: ...`` line on stderr and exit code 2 (a truncated file
names ``stewart-vibration mcap-recover``). SIGINT/SIGTERM stop the replay
thread before the node and the context are torn down, so stopping logs no
error. Prints ``MCAP_REPLAY_DONE {json}`` at the end; exit 0, or 1 if the
replay failed.
"""

from __future__ import annotations

import itertools
import json
import sys
import threading
import time

import numpy as np
import rclpy
import rclpy.executors
from rclpy.node import Node
from rosgraph_msgs.msg import Clock

from ..errors import StewartError
from ..mcap_log.qos_yaml import offer_for_replay, parse_qos_profiles
from ..mcap_log.reader import open_run
from ..mcap_log.replay_schedule import ClockTick, Pacer, ReplayOptions, recorded_rate_hz, schedule, with_clock
from ..parameters.tables import MCAP_REPLAY, REPLAY_CLOCK_RATE_HZ
from .node_parameters import declare_table
from .ros_graph import message_class, rclpy_profile
from .run_loop import StopFlag, guard_sim_clock, init_rclpy, make_executor

SUBSCRIBERS_SETTLE_S = 1.0  # wall s the subscriber counts must stay unchanged before a waiting replay starts


def _clock_msg(t_ns: int) -> Clock:
    msg = Clock()
    msg.clock.sec, msg.clock.nanosec = divmod(int(t_ns), 1_000_000_000)
    return msg


class McapReplayNode(Node):
    """Owns one publisher per replayed topic and a replay thread."""

    def __init__(self, **kwargs):
        super().__init__("mcap_replay", **kwargs)
        params = declare_table(self, MCAP_REPLAY)
        path, rate, offset = params["path"], params["rate"], params["start_offset_s"]
        self.loop, self.publish_clock = params["loop"], params["publish_clock"]
        clock_rate = params["clock_rate_hz"]
        include = [t for t in params["topics"] if t]
        exclude = [t for t in params["exclude_topics"] if t]
        self.wait_s, self.exit_when_done = params["wait_for_subscribers_s"], params["exit_when_done"]
        if not path:
            raise ValueError("parameter 'path' (the .mcap or run folder to replay) is required")
        self.reader = open_run(path)
        if self.publish_clock:
            exclude.append("/clock")
            if clock_rate == 0:
                recorded = recorded_rate_hz([m.log_time for m in self.reader.messages(["/clock"])])
                clock_rate = recorded or REPLAY_CLOCK_RATE_HZ
        self.clock_rate_hz = clock_rate
        self.options = ReplayOptions(rate=rate, start_offset_s=offset, include=tuple(include), exclude=tuple(exclude))
        self.pubs = {}
        for info in self.reader.topics():
            if not self.options.wants(info.topic) or info.message_count == 0:
                continue
            qos = rclpy_profile(offer_for_replay(parse_qos_profiles(info.offered_qos_profiles)))
            self.pubs[info.topic] = self.create_publisher(message_class(info.type_name), info.topic, qos)
        self.clock_pub = self.create_publisher(Clock, "/clock", 10) if self.publish_clock else None
        self.published = {t: 0 for t in self.pubs}
        self.clocks_published = 0
        self.lateness_s: list[float] = []
        self.failure: str | None = None
        self.done = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="mcap-replay", daemon=True)
        self._thread.start()

    def _wait_for_subscribers(self) -> None:
        """Until every publisher is matched, by at least every subscriber the ROS graph shows on its topic, and
        no count has changed for SUBSCRIBERS_SETTLE_S (a subscriber still matching would miss the start: CI
        under load lost 1.7 s of a run's states that way, and a CPU-hog run 0.5 s of one subscriber's), or until
        wait_for_subscribers_s has passed."""
        deadline = time.monotonic() + self.wait_s
        counts, since = None, time.monotonic()
        while time.monotonic() < deadline and not self._stop.is_set():
            matched = [p.get_subscription_count() for p in self.pubs.values()]
            discovered = [self.count_subscribers(topic) for topic in self.pubs]
            now_counts = matched + discovered
            if now_counts != counts:
                counts, since = now_counts, time.monotonic()
            elif all(matched) and all(m >= d for m, d in zip(matched, discovered, strict=True)) and \
                    time.monotonic() - since >= SUBSCRIBERS_SETTLE_S:
                return
            time.sleep(0.05)

    def _items(self, run_start: int):
        items = schedule(self.reader.messages(), run_start, self.options)
        if self.clock_pub is None:
            return items
        return with_clock(items, self.options.start_ns(run_start), self.options, self.clock_rate_hz)

    def _run(self) -> None:
        try:
            self._wait_for_subscribers()
            run_start = min((m.log_time for m in self.reader.messages()), default=0)
            while not self._stop.is_set():
                items = self._items(run_start)
                first = next(items, None)  # open the file and decode the first chunk first
                if first is None:
                    break
                pacer = Pacer()  # time zero of the replay is now
                for due, item in itertools.chain([first], items):
                    late = pacer.wait_until(due, self._stop.is_set)
                    if self._stop.is_set():
                        break
                    if isinstance(item, ClockTick):
                        self.clock_pub.publish(_clock_msg(item.clock_ns))
                        self.clocks_published += 1
                        continue
                    self.lateness_s.append(late)
                    pub = self.pubs.get(item.topic)
                    if pub is not None:
                        pub.publish(item.data)
                        self.published[item.topic] += 1
                if not self.loop:
                    break
        except Exception as exc:  # noqa: BLE001 - reported (unless we are stopping), then the node exits
            if not self._stop.is_set():
                self.failure = f"{type(exc).__name__}: {exc}"
                self.get_logger().error(f"replay failed: {self.failure}")
        finally:
            self.done.set()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5.0)


def _report(node: McapReplayNode) -> dict:
    late = np.asarray(node.lateness_s or [0.0])
    order = np.argsort(late)  # message indices, least to most late
    return {
        "published": node.published,
        "clock_published": node.clocks_published,
        "clock_rate_hz": node.clock_rate_hz if node.publish_clock else None,
        "failure": node.failure,
        "lateness_max_s": float(late[order[-1]]),
        "lateness_p99_s": float(late[order[int(0.99 * (len(late) - 1))]]),
        "lateness_worst": [[int(i), float(late[i])] for i in order[::-1][:5]],
    }


def main(args=None) -> int:
    """Run the mcap_replay node until the replay is done (if the node exits when done) or SIGINT / SIGTERM.

    Prints ``MCAP_REPLAY_DONE`` and the replay's JSON report at the end. Returns 0, 1 if the replay
    failed, 2 if the node cannot start (bad parameter or unusable MCAP: one ``error:`` line).
    """
    # The replay thread must get the GIL back within well under 1 ms of its due time.
    sys.setswitchinterval(1e-4)
    if not init_rclpy(args, "mcap_replay: error:"):
        return 2
    guard_sim_clock()  # a /clock that is no time is dropped (it raised in rclpy's clock callback)
    stop = StopFlag().install()  # a flag only: a stop during start-up still finishes cleanly
    try:
        node = McapReplayNode()
    except (StewartError, ValueError, rclpy.exceptions.ParameterException) as exc:
        print(f"mcap_replay: error: {exc}", file=sys.stderr, flush=True)
        rclpy.try_shutdown()
        return 2
    executor = make_executor()
    executor.add_node(node)
    try:
        while rclpy.ok() and not stop.is_set():
            if node.exit_when_done and node.done.is_set():
                time.sleep(0.3)  # let reliable readers receive the tail
                break
            executor.spin_once(timeout_sec=0.05)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    finally:
        node.stop()
        print("MCAP_REPLAY_DONE " + json.dumps(_report(node)), flush=True)
        executor.remove_node(node)
        node.destroy_node()
        rclpy.try_shutdown()
    return 1 if node.failure else 0


if __name__ == "__main__":
    sys.exit(main())
