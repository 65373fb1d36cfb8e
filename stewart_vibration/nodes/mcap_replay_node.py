"""mcap_replay: republish a recorded MCAP run with its original timing.

The recorded CDR bytes are published as they are (Publisher.publish(bytes), no
re-serialisation), each topic with the QoS its publishers offered in the
recording. Message k is published at (log_time_k - t0) / rate after the start.

Parameters: path (str, the .mcap), rate (1.0), start_offset_s (0.0, s into the
run), loop (false), publish_clock (false: publish /clock = log time of each
message; the recorded /clock is then not replayed), topics (str[], empty =
all), exclude_topics (str[]), wait_for_subscribers_s (0.0: wait up to this
long for every replay publisher to be matched before starting),
exit_when_done (true). Prints ``MCAP_REPLAY_DONE {json}`` at the end.
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

from ..mcap_log.qos_yaml import offer_for_replay, parse_qos_profiles
from ..mcap_log.reader import RunReader
from ..mcap_log.replay_schedule import Pacer, ReplayOptions, schedule
from .mcap_ros import make_executor, message_class, rclpy_profile, spin_until_shutdown


def _clock_msg(t_ns: int) -> Clock:
    msg = Clock()
    msg.clock.sec, msg.clock.nanosec = divmod(int(t_ns), 1_000_000_000)
    return msg


class McapReplayNode(Node):
    """Owns one publisher per replayed topic and a replay thread."""

    def __init__(self, **kwargs):
        super().__init__("mcap_replay", **kwargs)
        self.declare_parameter("path", "")
        self.declare_parameter("rate", 1.0)
        self.declare_parameter("start_offset_s", 0.0)
        self.declare_parameter("loop", False)
        self.declare_parameter("publish_clock", False)
        self.declare_parameter("topics", [""])
        self.declare_parameter("exclude_topics", [""])
        self.declare_parameter("wait_for_subscribers_s", 0.0)
        self.declare_parameter("exit_when_done", True)
        param = self.get_parameter
        path = str(param("path").value)
        if not path:
            raise ValueError("parameter 'path' (the .mcap to replay) is required")
        self.reader = RunReader(path)
        self.publish_clock = bool(param("publish_clock").value)
        exclude = [t for t in param("exclude_topics").value if t]
        if self.publish_clock:
            exclude.append("/clock")
        self.options = ReplayOptions(
            rate=float(param("rate").value),
            start_offset_s=float(param("start_offset_s").value),
            include=tuple(t for t in param("topics").value if t),
            exclude=tuple(exclude),
        )
        self.loop = bool(param("loop").value)
        self.pubs = {}
        for info in self.reader.topics():
            if not self.options.wants(info.topic) or info.message_count == 0:
                continue
            qos = rclpy_profile(offer_for_replay(parse_qos_profiles(info.offered_qos_profiles)))
            self.pubs[info.topic] = self.create_publisher(message_class(info.type_name), info.topic, qos)
        self.clock_pub = self.create_publisher(Clock, "/clock", 10) if self.publish_clock else None
        self.published = {t: 0 for t in self.pubs}
        self.lateness_s: list[float] = []
        self.done = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="mcap-replay", daemon=True)
        self._thread.start()

    def _wait_for_subscribers(self) -> None:
        deadline = time.monotonic() + float(self.get_parameter("wait_for_subscribers_s").value)
        while time.monotonic() < deadline and not self._stop.is_set():
            if all(p.get_subscription_count() > 0 for p in self.pubs.values()):
                time.sleep(0.3)  # finish the reliable handshake
                return
            time.sleep(0.05)

    def _run(self) -> None:
        try:
            self._wait_for_subscribers()
            run_start = min((m.log_time for m in self.reader.messages()), default=0)
            while not self._stop.is_set():
                items = schedule(self.reader.messages(), run_start, self.options)
                first = next(items, None)  # open the file and decode the first chunk first
                if first is None:
                    break
                pacer = Pacer()  # time zero of the replay is now
                for due, msg in itertools.chain([first], items):
                    late = pacer.wait_until(due, self._stop.is_set)
                    self.lateness_s.append(late)
                    if self._stop.is_set():
                        break
                    if self.clock_pub is not None:
                        self.clock_pub.publish(_clock_msg(msg.log_time))
                    pub = self.pubs.get(msg.topic)
                    if pub is not None:
                        pub.publish(msg.data)
                        self.published[msg.topic] += 1
                if not self.loop:
                    break
        except Exception as exc:  # noqa: BLE001 - reported, then the node exits
            self.get_logger().error(f"replay failed: {exc}")
        finally:
            self.done.set()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5.0)


def main(args=None) -> int:
    # The replay thread must get the GIL back within well under 1 ms of its due time.
    sys.setswitchinterval(1e-4)
    rclpy.init(args=args)
    node = McapReplayNode()
    executor = make_executor()
    executor.add_node(node)
    try:
        if node.get_parameter("exit_when_done").value:
            while rclpy.ok() and not node.done.is_set():
                executor.spin_once(timeout_sec=0.05)
            time.sleep(0.3)  # let reliable readers receive the tail
        else:
            spin_until_shutdown(executor)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    finally:
        node.stop()
        late = np.asarray(node.lateness_s or [0.0])
        order = np.argsort(late)  # message indices, least to most late
        report = {
            "published": node.published,
            "lateness_max_s": float(late[order[-1]]),
            "lateness_p99_s": float(late[order[int(0.99 * (len(late) - 1))]]),
            "lateness_worst": [[int(i), float(late[i])] for i in order[::-1][:5]],
        }
        print("MCAP_REPLAY_DONE " + json.dumps(report), flush=True)
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
