"""A stand-in for the ``ros2`` command (ros2cli is not on PyPI), so the README's ``ros2 ...`` lines run here
exactly as written, over real DDS with rclpy.

It implements the verbs the README uses, with ros2cli's arguments and output shape:

  ros2 topic pub --once TOPIC TYPE YAML     waits for one matching subscription, publishes once
  ros2 topic echo [--once] TOPIC [TYPE]     prints each message, then ``---`` (until Ctrl-C)
  ros2 service call SERVICE TYPE [YAML]     waits for the service, prints ``response:`` and the answer
  ros2 param set NODE NAME VALUE            VALUE parsed as YAML, as ros2cli does ("0.3" double, "[..]" array)
  ros2 action send_goal [-f] ACTION TYPE YAML  sends the goal, prints the feedback (-f / --feedback), the
                                            result and ``Goal finished with status: ...``; Ctrl-C cancels it
  ros2 run PACKAGE EXECUTABLE [ARGS...]     executes <prefix>/lib/PACKAGE/EXECUTABLE, prefix from the ament index

Stricter than ros2cli in one way: a refused ``param set``, an unsuccessful Trigger or a goal that did not
succeed exits 1, so a test sees it. Sturdier in one: a query (``param set``, ``get_state``, ...) whose answer
Fast DDS lost is asked again
(nodes.service_calls). ``ros2 launch`` and ``ros2 bag`` need a ROS install; they exit 2 saying so.
"""

from __future__ import annotations

import importlib
import os
import sys
import time
from pathlib import Path

import yaml

from stewart_vibration.runtime.interrupts import INTERRUPTS

WAIT_S = 30.0


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


def topic_pub(node, args: list[str]) -> int:
    if args[0] != "--once":
        raise SystemExit("this stand-in publishes with --once only")
    topic, type_name, text = args[1], args[2], args[3] if len(args) > 3 else None
    msg = fill(message_type(type_name)(), parse_yaml(text))
    publisher = node.create_publisher(type(msg), topic, 10)
    print("publisher: beginning loop")
    wait_for(lambda: publisher.get_subscription_count() >= 1, f"a subscription on {topic}")
    publisher.publish(msg)
    print(f"publishing #1: {msg!r}\n")
    time.sleep(0.2)  # let reliable delivery finish before the participant goes away
    return 0


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


def spinner(node):
    """``wait(predicate, seconds) -> bool`` spinning ``node`` (for nodes.service_calls.answer_with_resend:
    a lost answer to a query is asked again, which ros2cli does not do)."""
    import rclpy

    def wait(predicate, seconds: float) -> bool:
        deadline = time.monotonic() + seconds
        while not predicate() and time.monotonic() < deadline:
            with INTERRUPTS.deferred():
                rclpy.spin_once(node, timeout_sec=0.05)
        return bool(predicate())
    return wait


def service_call(node, args: list[str]) -> int:
    from stewart_vibration.nodes.service_calls import answer_with_resend

    name, type_name = args[0], args[1]
    srv = message_type(type_name)
    request = fill(srv.Request(), parse_yaml(args[2] if len(args) > 2 else None))
    client = node.create_client(srv, name)
    if not client.wait_for_service(timeout_sec=WAIT_S):
        raise SystemExit(f"service {name} not available after {WAIT_S:g} s")
    print(f"requester: making request: {request!r}\n")
    response = answer_with_resend(client, name, request, WAIT_S, spinner(node))
    if response is None:
        raise SystemExit(f"no response from {name} in {WAIT_S:g} s")
    print(f"response:\n{response!r}\n")
    refused = getattr(response, "success", True) is False or \
        (hasattr(response, "outcome") and response.outcome.code != 1)  # Outcome.SUCCEEDED
    return 1 if refused else 0


def param_set(node, args: list[str]) -> int:
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter

    from stewart_vibration.nodes.service_calls import answer_with_resend

    target, name, text = args[0], args[1], args[2]
    value = yaml.safe_load(text)
    client = node.create_client(SetParameters, f"{target}/set_parameters")
    if not client.wait_for_service(timeout_sec=WAIT_S):
        raise SystemExit(f"Node not found: {target}")
    request = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
    answer = answer_with_resend(client, f"{target}/set_parameters", request, WAIT_S, spinner(node))
    if answer is None:
        raise SystemExit(f"no response from {target}/set_parameters in {WAIT_S:g} s")
    (result,) = answer.results
    if result.successful:
        print("Set parameter successful")
        return 0
    print(f"Setting parameter failed: {result.reason}")
    return 1


def action_send_goal(node, args: list[str]) -> int:
    from rclpy.action import ActionClient

    feedback = any(a in ("-f", "--feedback") for a in args)
    args = [a for a in args if a not in ("-f", "--feedback")]
    name, type_name = args[0], args[1]
    action = message_type(type_name)
    goal = fill(action.Goal(), parse_yaml(args[2] if len(args) > 2 else None))
    client = ActionClient(node, action, name)
    print("Waiting for an action server to become available...")
    if not client.wait_for_server(timeout_sec=WAIT_S):
        raise SystemExit(f"action {name} not available after {WAIT_S:g} s")
    wait = spinner(node)
    wait(lambda: False, 0.5)  # discovery finishes (a goal's answer sent before it is lost; it cannot be resent)
    print(f"Sending goal:\n     {goal!r}\n")
    sent = client.send_goal_async(goal, feedback_callback=(lambda m: print(f"Feedback:\n    {m.feedback!r}\n"))
                                  if feedback else None)
    if not wait(sent.done, WAIT_S) or not sent.result().accepted:
        print("Goal was rejected.")
        return 1
    handle = sent.result()
    print(f"Goal accepted with ID: {bytes(handle.goal_id.uuid).hex()}\n")
    result = handle.get_result_async()
    try:
        while not wait(result.done, 1.0):
            pass
    except KeyboardInterrupt:
        cancel = handle.cancel_goal_async()
        wait(cancel.done, WAIT_S)
        print("Goal canceled.")
        wait(result.done, WAIT_S)
    if not result.done():
        return 1
    answer = result.result()
    status = {4: "SUCCEEDED", 5: "CANCELED", 6: "ABORTED"}.get(answer.status, str(answer.status))
    print(f"Result:\n    {answer.result!r}\n\nGoal finished with status: {status}")
    return 0 if status == "SUCCEEDED" else 1


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
        return verb(node, argv[2:])
    except KeyboardInterrupt:
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
