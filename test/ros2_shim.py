"""A stand-in for the ``ros2`` command (ros2cli is not on PyPI), so the ``ros2 ...`` lines of the README and
the docs pages run here exactly as written, over real DDS with rclpy.

It implements the verbs they use with ros2cli 0.32's arguments, waiting, output shape and exit codes,
and is no sturdier than it: nothing is resent, a lost answer is lost (here it ends after WAIT_S with exit 1
where ros2cli would wait forever; a server not yet discovered is waited for DISCOVERY_WAIT_S), and a
refusal in an answer exits 0 as in ros2cli (tests read the output, as a user does):

  ros2 topic pub [--once|-1] [-t N] [-w N] [--max-wait-time-secs S] [--keep-alive S] TOPIC TYPE [YAML]
                          waits for N matching subscriptions (default 1 with --once/-t, else 0), publishes,
                          keeps the participant alive --keep-alive s (default 0.1)
  ros2 topic echo [--once] TOPIC [TYPE]     prints each message, then ``---`` (until Ctrl-C)
  ros2 service call SERVICE TYPE [YAML]     waits for the service, one request, prints ``response:`` and it
  ros2 param set NODE NAME VALUE            VALUE parsed as YAML; "Set parameter successful" or
                                            "Setting parameter failed: REASON" on stderr (exit 0 both)
  ros2 action send_goal [-f] ACTION TYPE YAML  sends the goal at once, prints the feedback (-f / --feedback),
                                            the result and ``Goal finished with status: ...``; Ctrl-C cancels it
  ros2 run PACKAGE EXECUTABLE [ARGS...]     executes <prefix>/lib/PACKAGE/EXECUTABLE, prefix from the ament index

Messages print as repr (ros2cli prints action messages as YAML with rosidl_runtime_py, not on PyPI).
``ros2 launch`` and ``ros2 bag`` need a ROS install; they exit 2 saying so.
"""

from __future__ import annotations

import importlib
import os
import sys
import time
from pathlib import Path

import yaml

from stewart_vibration.runtime.interrupts import INTERRUPTS

WAIT_S = 30.0  # for an answer
# for a service or action server to be discovered: ros2cli waits forever; on a loaded 2-core machine a fresh
# participant has taken over 30 s to see a server that was up all along
DISCOVERY_WAIT_S = 120.0


def message_type(name: str):
    """``pkg/msg/Type`` (or ``pkg/Type``) -> the generated class; services too (``pkg/srv/Type``)."""
    parts = name.split("/")
    if len(parts) == 2:
        parts = [parts[0], "msg", parts[1]]
    pkg, kind, cls = parts
    return getattr(importlib.import_module(f"{pkg}.{kind}"), cls)


def fill(msg, values: dict | None):
    """Set ``msg``'s fields from a (nested) dict, as ros2cli's set_message_fields does."""
    types = msg.get_fields_and_field_types()
    for key, value in (values or {}).items():
        current = getattr(msg, key)  # AttributeError names an unknown field
        if isinstance(value, dict):
            fill(current, value)
        elif isinstance(value, list) and any(isinstance(v, dict) for v in value):  # a sequence of messages
            element = types[key].removeprefix("sequence<").split(",")[0].rstrip(">").split("[")[0]
            setattr(msg, key, [fill(message_type(element)(), v) for v in value])
        elif isinstance(current, float) and isinstance(value, int):
            setattr(msg, key, float(value))
        elif isinstance(value, list) and len(current) and isinstance(current[0], float):  # float64[N]
            setattr(msg, key, [float(v) for v in value])
        else:
            setattr(msg, key, value)
    return msg


def parse_yaml(text: str | None) -> dict:
    value = yaml.safe_load(text) if text else {}
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise SystemExit(f"The passed value needs to be a dictionary in YAML format, got {text!r}")
    return value


def wait_for(predicate, what: str) -> None:
    deadline = time.monotonic() + WAIT_S
    while not predicate():
        if time.monotonic() > deadline:
            raise SystemExit(f"timed out after {WAIT_S:g} s waiting for {what}")
        time.sleep(0.05)


def topic_pub(node, args: list[str]) -> int | str:
    """ros2topic's pub verb for --once / --times: wait for -w subscriptions, publish, keep alive."""
    import argparse

    parser = argparse.ArgumentParser(prog="ros2 topic pub")
    parser.add_argument("topic_name")
    parser.add_argument("message_type")
    parser.add_argument("values", nargs="?", default="{}")
    parser.add_argument("-1", "--once", action="store_true")
    parser.add_argument("-t", "--times", type=int, default=0)
    parser.add_argument("-r", "--rate", type=float, default=1.0)
    parser.add_argument("-w", "--wait-matching-subscriptions", type=int, default=None)
    parser.add_argument("--max-wait-time-secs", type=float, default=None)
    parser.add_argument("--keep-alive", type=float, default=0.1)
    opts = parser.parse_args(args)
    times = 1 if opts.once else opts.times
    if times == 0:
        raise SystemExit("this stand-in publishes a finite number of messages only (--once or --times N)")
    wait = opts.wait_matching_subscriptions if opts.wait_matching_subscriptions is not None else 1
    values = yaml.safe_load(opts.values)
    if not isinstance(values, dict):
        return "The passed value needs to be a dictionary in YAML format"
    msg = fill(message_type(opts.message_type)(), values)
    publisher = node.create_publisher(type(msg), opts.topic_name, 10)
    waited = 0.0
    while publisher.get_subscription_count() < wait:
        if waited % 1.0 < 0.05:
            print(f"Waiting for at least {wait} matching subscription(s)...")
        if opts.max_wait_time_secs is not None and opts.max_wait_time_secs <= waited:
            return (f"Timed out waiting for subscribers: Expected {wait} subcribers but only got "
                    f"{publisher.get_subscription_count()} subscribers")
        time.sleep(0.1)
        waited += 0.1
    print("publisher: beginning loop")
    for count in range(1, times + 1):
        print(f"publishing #{count}: {msg!r}\n")
        publisher.publish(msg)
        if count < times:
            time.sleep(1.0 / opts.rate)
    time.sleep(opts.keep_alive)  # as ros2cli: a moment for the message to reach the wire
    return None


def topic_echo(node, args: list[str]) -> int:
    import rclpy

    once = "--once" in args
    rest = [a for a in args if a != "--once"]
    topic = rest[0]
    if len(rest) > 1:
        msg_class = message_type(rest[1])
    else:
        def known():
            return dict(node.get_topic_names_and_types()).get(topic)

        wait_for(known, f"topic {topic} to appear")
        msg_class = message_type(known()[0])
    received = []

    def show(msg):
        print(f"{msg!r}\n---", flush=True)
        received.append(msg)

    node.create_subscription(msg_class, topic, show, 10)
    while rclpy.ok() and not (once and received):
        with INTERRUPTS.deferred():  # Ctrl-C inside rclpy's C++ aborted or hung it (CI: 180 s, no exit)
            rclpy.spin_once(node, timeout_sec=0.1)
    return 0


def wait_until(node, predicate, seconds: float) -> bool:
    """Spin ``node`` until ``predicate()`` or ``seconds`` passed (ros2cli spins without a limit)."""
    import rclpy

    deadline = time.monotonic() + seconds
    while not predicate() and time.monotonic() < deadline:
        with INTERRUPTS.deferred():
            rclpy.spin_once(node, timeout_sec=0.05)
    return bool(predicate())


def note_slow_discovery(name: str, since: float) -> None:
    """Say on stderr (not in the output a test reads) when finding ``name`` took more than 5 s."""
    waited = time.monotonic() - since
    if waited > 5.0:
        print(f"(shim) {name} was discovered after {waited:.1f} s", file=sys.stderr)


def service_call(node, args: list[str]) -> int | str:
    """One request, as ros2service's call: a response that never comes is not asked for again."""
    name, type_name = args[0], args[1]
    srv = message_type(type_name)
    request = fill(srv.Request(), parse_yaml(args[2] if len(args) > 2 else None))
    client = node.create_client(srv, name)
    if not client.service_is_ready():
        print("waiting for service to become available...")
        waited_from = time.monotonic()
        if not client.wait_for_service(timeout_sec=DISCOVERY_WAIT_S):
            raise SystemExit(f"(shim) service {name} not available after {DISCOVERY_WAIT_S:g} s")
        note_slow_discovery(name, waited_from)
    print(f"requester: making request: {request!r}\n")
    future = client.call_async(request)
    if not wait_until(node, future.done, WAIT_S):
        raise SystemExit(f"(shim) no response from {name} in {WAIT_S:g} s (ros2cli would wait forever)")
    print(f"response:\n{future.result()!r}\n")
    return None


def param_set(node, args: list[str]) -> int | str:
    """ros2param's set: a refusal is printed on stderr and exits 0, as there."""
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter

    target, name, text = args[0], args[1], args[2]
    value = yaml.safe_load(text)
    client = node.create_client(SetParameters, f"{target}/set_parameters")
    if not client.wait_for_service(timeout_sec=WAIT_S):
        return "Node not found"
    request = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
    future = client.call_async(request)
    if not wait_until(node, future.done, WAIT_S):
        raise SystemExit(f"(shim) no response from {target}/set_parameters in {WAIT_S:g} s")
    (result,) = future.result().results
    if result.successful:
        print("Set parameter successful")
    else:
        print(f"Setting parameter failed: {result.reason}" if result.reason else "Setting parameter failed",
              file=sys.stderr)
    return None


def action_send_goal(node, args: list[str]) -> int | str:
    """ros2action's send_goal: the goal is sent as soon as the server is seen; every end exits 0."""
    from rclpy.action import ActionClient

    feedback = any(a in ("-f", "--feedback") for a in args)
    args = [a for a in args if a not in ("-f", "--feedback")]
    name, type_name = args[0], args[1]
    action = message_type(type_name)
    goal = fill(action.Goal(), parse_yaml(args[2] if len(args) > 2 else None))
    client = ActionClient(node, action, name)
    print("Waiting for an action server to become available...")
    waited_from = time.monotonic()
    if not client.wait_for_server(timeout_sec=DISCOVERY_WAIT_S):
        raise SystemExit(f"(shim) action {name} not available after {DISCOVERY_WAIT_S:g} s (ros2cli would wait "
                         "forever)")
    note_slow_discovery(name, waited_from)
    print(f"Sending goal:\n     {goal!r}")
    sent = client.send_goal_async(goal, feedback_callback=(lambda m: print(f"Feedback:\n    {m.feedback!r}"))
                                  if feedback else None)
    if not wait_until(node, sent.done, WAIT_S):
        raise SystemExit(f"(shim) no answer to the goal from {name} in {WAIT_S:g} s")
    if not sent.result().accepted:
        print("Goal was rejected.")
        return None
    handle = sent.result()
    print(f"Goal accepted with ID: {bytes(handle.goal_id.uuid).hex()}\n")
    result = handle.get_result_async()
    try:
        while not wait_until(node, result.done, 1.0):
            pass
    except KeyboardInterrupt:
        print("Canceling goal...")
        cancel = handle.cancel_goal_async()
        wait_until(node, cancel.done, WAIT_S)
        print("Goal canceled.")
        wait_until(node, result.done, WAIT_S)
    if not result.done():
        return "(shim) the goal's result never came"
    answer = result.result()
    status = {4: "SUCCEEDED", 5: "CANCELED", 6: "ABORTED"}.get(answer.status, "UNKNOWN")
    print(f"Result:\n    {answer.result!r}")
    print(f"Goal finished with status: {status}")
    return None


def run(args: list[str]) -> int:
    """As ros2cli's run verb: the package's prefix from the ament index (not any prefix that happens to hold
    the file), then its lib/<package>/<executable>."""
    from ament_index_python.packages import PackageNotFoundError, get_package_prefix

    package, executable, rest = args[0], args[1], args[2:]
    try:
        prefix = get_package_prefix(package)
    except PackageNotFoundError:
        raise SystemExit(f"Package '{package}' not found") from None
    path = Path(prefix) / "lib" / package / executable
    if path.is_file() and os.access(path, os.X_OK):
        os.execv(str(path), [str(path), *rest])
    raise SystemExit("No executable found")


VERBS = {("topic", "pub"): topic_pub, ("topic", "echo"): topic_echo, ("service", "call"): service_call,
         ("param", "set"): param_set, ("action", "send_goal"): action_send_goal}


def main(argv: list[str]) -> int:
    if argv[:1] == ["run"]:
        return run(argv[1:])
    verb = VERBS.get(tuple(argv[:2]))
    if verb is None:
        print(f"ros2 {' '.join(argv[:2])}: needs a ROS install (ros2cli, launch and rosbag2 are not on PyPI)",
              file=sys.stderr)
        return 2
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    INTERRUPTS.install()
    node = rclpy.create_node(f"ros2cli_shim_{os.getpid()}")
    try:
        error = verb(node, argv[2:])
    except KeyboardInterrupt:
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    if error:  # as ros2cli's main: a returned string is printed and exits 1
        print(error, file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
