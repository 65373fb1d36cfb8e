"""``stewart-vibration topic-rate TOPIC``: a topic's true rate, as a subscriber that loses nothing sees it.

It subscribes with the QoS the publishers offer (reliable where they are, as rosbag2 does) and a queue of
``--depth`` messages, so the suite's bursts of 10 samples are not cut as ``ros2 topic hz`` cuts them (best
effort, queue of 5), and reports the messages per second of wall time and, for stamped messages, per second
of the publisher's clock (sim time in a suite) with the samples missing from the stamps (messages.topic_rate).

Exit codes: 0 messages received; 1 no message within --seconds; 2 no publisher of TOPIC within --wait s, or
bad arguments.
"""

from __future__ import annotations

import json

from .arguments import float_in, int_in


def register(subparsers) -> None:
    """Add the ``topic-rate`` subcommand to ``subparsers``."""
    p = subparsers.add_parser(
        "topic-rate",
        help="a topic's true rate (reliable, deep queue; stamps), where ros2 topic hz drops burst samples",
        description="Measure TOPIC's rate for --seconds of wall time with the publishers' reliability and a deep "
                    "queue: messages per wall second and, for stamped messages, per second of their stamps' "
                    "clock, with the samples missing from the stamps. Uses ROS_DOMAIN_ID as every node does.",
    )
    p.add_argument("topic", help="full topic name, e.g. /stewart/platform/pose_estimate")
    p.add_argument("--seconds", type=float_in(0.5, 3600.0, "s"), default=5.0, help="how long to listen (wall s)")
    p.add_argument("--wait", type=float_in(0.0, 600.0, "s"), default=10.0,
                   help="how long to wait for a publisher of TOPIC (wall s)")
    p.add_argument("--depth", type=int_in(1, 1_000_000), default=5000, help="subscription queue (messages)")
    p.add_argument("--json", action="store_true", help="print the figures as JSON")
    p.set_defaults(func=run)


def run(args) -> int:
    """Listen to ``args.topic`` and print its rate; the exit code (module docstring)."""
    from ..messages.topic_rate import topic_rate
    from ..nodes.topic_listener import listen

    heard = listen(args.topic, args.seconds, args.wait, args.depth)
    if heard is None:
        print(f"no publisher of {args.topic} within {args.wait:g} s (is ROS_DOMAIN_ID the suite's?)")
        return 2
    rate = topic_rate(heard.arrivals, heard.stamps if heard.stamped else None)
    type_name, qos = heard.type_name, heard.qos
    if args.json:
        print(json.dumps({"topic": args.topic, "type": type_name, "reliability": qos.reliability,
                          "depth": qos.depth, **rate.record()}))
    elif rate.count == 0:
        print(f"{args.topic}: no message in {args.seconds:g} s")
    else:
        line = f"{args.topic} ({type_name}, {qos.reliability}, depth {qos.depth}): {rate.count} messages, " \
               f"{rate.wall_hz:.1f} per wall second"
        if rate.stamped and rate.stamp_hz == rate.stamp_hz:
            line += (f"; stamps: {rate.stamp_hz:.1f} per second over {rate.stamp_span_s:.3f} s, period "
                     f"{rate.period_s * 1e3:.3f} ms, {rate.missing} missing, largest gap "
                     f"{rate.largest_gap_s * 1e3:.1f} ms")
        print(line)
    return 0 if rate.count else 1
