"""A real rclpy client for integration tests: own Context on the test's ROS domain.

Nodes under test run as separate processes (stewart_vibration.runtime.processes);
this client publishes, subscribes and calls services over real DDS.
"""

from __future__ import annotations

import os
import time
from collections import defaultdict
from contextlib import contextmanager

import rclpy
from lifecycle_msgs.srv import ChangeState, GetState
from rclpy.context import Context
from rclpy.node import Node

import stewart_vibration.nodes  # noqa: F401  (AMENT_PREFIX_PATH in the pip world)
from stewart_vibration.nodes.run_loop import make_executor
from stewart_vibration.nodes.service_calls import (
    GoalAcceptances,
    ServiceClients,
    answer_with_resend,
    send_goal_recovering,
    transition_lifecycle,
)
from stewart_vibration.runtime.processes import ros_environment, start_python_module


class ActionGoal:
    """An action goal a test sent (vibrate, move_to_pose): its feedback as it comes, its result and outcome once
    it ends."""

    def __init__(self, client: RosTestClient):
        self.client, self.feedback, self.handle, self.result_future = client, [], None, None
        self.feedback_times: list[float] = []  # wall arrival time (monotonic s) of each feedback

    def on_feedback(self, msg) -> None:
        self.feedback_times.append(time.monotonic())
        self.feedback.append(msg)

    def plan(self, timeout: float = 20.0):
        """The plan (VibrationPlan) of the first feedback; None if the goal ended without one."""
        self.client.spin_until(lambda: self.feedback or self.result_future.done(), timeout)
        return self.feedback[0].feedback.plan if self.feedback else None

    def result(self, timeout: float = 30.0):
        """The result once the goal ended (TimeoutError if it did not within ``timeout`` s)."""
        if not self.client.spin_until(self.result_future.done, timeout):
            raise TimeoutError("the goal did not end")
        return self.result_future.result().result

    def outcome(self, timeout: float = 30.0) -> tuple[str, str]:
        """(the result's outcome name, its message)."""
        from stewart_vibration.nodes.outcomes import outcome_name

        result = self.result(timeout)
        return outcome_name(result.outcome.code), result.outcome.message

    def status(self) -> int:
        """The goal's final status (action_msgs/GoalStatus: 4 succeeded, 5 canceled, 6 aborted)."""
        return self.result_future.result().status

    def cancel(self, timeout: float = 10.0) -> None:
        future = self.handle.cancel_goal_async()
        if not self.client.spin_until(future.done, timeout):
            raise TimeoutError("the cancel was not answered")


class RosTestClient:
    """Node + executor on ROS_DOMAIN_ID; records every message it subscribes to."""

    def __init__(self, name: str = "test_client"):
        self.context = Context()
        self.context.init(domain_id=int(os.environ.get("ROS_DOMAIN_ID", "0")))
        self.node = Node(name, context=self.context)
        self.executor = make_executor(self.context)  # EventsExecutor: keeps up with the 500 Hz streams
        self.executor.add_node(self.node)
        self.received = defaultdict(list)
        self._publishers = {}
        self._subscriptions: dict = {}
        self.clients = ServiceClients(self.node)
        self._actions: dict = {}
        self._acceptances: dict = {}

    def subscribe(self, topic: str, msg_type, depth: int = 1000):
        self._subscriptions[topic] = self.node.create_subscription(msg_type, topic, self.received[topic].append,
                                                                   depth)
        return self.received[topic]

    def wait_matched(self, topic: str, count: int = 1, timeout: float = 20.0) -> bool:
        """Spin until this client's subscription of ``topic`` has matched ``count`` publishers: a message sent
        before DDS matched them is lost (volatile QoS), and the graph shows them before that."""
        subscription = self._subscriptions[topic]
        return self.spin_until(lambda: subscription.get_publisher_count() >= count, timeout)

    def publisher(self, topic: str, msg_type, depth: int = 10):
        if topic not in self._publishers:
            self._publishers[topic] = self.node.create_publisher(msg_type, topic, depth)
        return self._publishers[topic]

    def spin_for(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.01)

    def spin_until(self, predicate, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if predicate():
                return True
            self.executor.spin_once(timeout_sec=0.01)
        return bool(predicate())

    def wait_for_subscribers(self, topic: str, count: int = 1, timeout: float = 20.0) -> bool:
        """Until `count` subscribers exist -- and, when this client publishes the topic, are matched
        to its publisher (the graph can list a reader before DDS has matched it: a message sent
        then is lost)."""
        def ready():
            pub = self._publishers.get(topic)
            if pub is not None:
                return pub.get_subscription_count() >= count
            return self.node.count_subscribers(topic) >= count
        return self.spin_until(ready, timeout)

    def call(self, srv_type, name: str, request, timeout: float = 20.0):
        """The service's answer (one kept client per service; a request to an idempotent service is sent
        again, see nodes.service_calls); TimeoutError if it is not up or does not answer."""
        client = self._ready_client(srv_type, name, timeout)
        answer = answer_with_resend(client, name, request, timeout, self.spin_until)
        if answer is None:
            raise TimeoutError(f"service {name} did not answer")
        return answer

    def transition(self, node: str, transition_id: int, timeout: float = 20.0) -> bool:
        """Lifecycle transition of ``node``: True if made, False if refused (a lost answer is recovered
        from the node's state, see nodes.service_calls.transition_lifecycle); TimeoutError otherwise."""
        client = self._ready_client(ChangeState, f"{node}/change_state", timeout)
        made = transition_lifecycle(client, transition_id, timeout, self.spin_until,
                                    lambda: self.lifecycle_state(node))
        if made is None:
            raise TimeoutError(f"{node}/change_state did not answer")
        return made

    def lifecycle_state(self, node: str) -> str:
        """The label of ``node``'s current lifecycle state (its get_state service)."""
        return self.call(GetState, f"{node}/get_state", GetState.Request()).current_state.label

    def _ready_client(self, srv_type, name: str, timeout: float):
        client = self.clients.get(srv_type, name)
        if not client.wait_for_service(timeout_sec=timeout):
            raise TimeoutError(f"service {name} not available")
        return client

    def vibrate_server_ready(self, timeout: float) -> bool:
        """Whether the planner's vibrate action is up within ``timeout`` s."""
        from stewart_vibration_interfaces.action import Vibrate

        return self.action_server_ready(Vibrate, "vibration_planner/vibrate", timeout)

    def action_server_ready(self, action_type, name: str, timeout: float) -> bool:
        """Whether the action ``name`` is up within ``timeout`` s (its client made on first use)."""
        from rclpy.action import ActionClient

        if name not in self._actions:
            self._actions[name] = ActionClient(self.node, action_type, name)
            self._acceptances[name] = GoalAcceptances(self.node, name)
            if not self.spin_until(self._actions[name].server_is_ready, timeout):
                return False
            # a goal sent at once can lose its answer (the server replies before it has matched this client's
            # reply reader: nodes.service_calls), and a goal cannot be sent twice: let discovery finish first
            self.spin_for(0.5)
        return self.spin_until(self._actions[name].server_is_ready, timeout)

    def send_goal(self, name: str, goal_msg, timeout: float = 20.0) -> ActionGoal:
        """Send ``goal_msg`` to the action ``name`` (ready: action_server_ready); returns once it was taken."""
        goal = ActionGoal(self)
        handle = send_goal_recovering(self._actions[name], goal_msg, self._acceptances[name], timeout, self.spin_until,
                                      feedback_callback=goal.on_feedback)
        if handle is None or not handle.accepted:
            raise TimeoutError(f"the {name} goal was not taken")
        goal.handle = handle
        goal.result_future = goal.handle.get_result_async()
        return goal

    def move(self, pose, timeout: float = 20.0, **values) -> ActionGoal:
        """Send kinematics' move_to_pose goal to ``pose`` (6,) (m, rad; base; ``values``: speed_scale,
        force_limit_n, moment_limit_nm, frame of nodes.move_messages.move_goal)."""
        from stewart_vibration.nodes.move_messages import MOVE_ACTION, move_goal
        from stewart_vibration_interfaces.action import MoveToPose

        if not self.action_server_ready(MoveToPose, MOVE_ACTION, timeout):
            raise TimeoutError(f"action {MOVE_ACTION} not available")
        return self.send_goal(MOVE_ACTION, move_goal(pose, **values), timeout)

    def vibrate(self, vibration: dict | None = None, timeout: float = 20.0, **values) -> ActionGoal:
        """Send a vibrate goal (the defaults of a 35 Hz / 0.3 g / 1 s vibration along the tibia axis, updated
        by ``vibration`` and ``values``); returns once the planner has taken it, with its handle."""
        from stewart_vibration.nodes.vibration_goal import goal_message

        settings = {"direction": [0.0, 0.0, 1.0], "frame": "platform", "amplitude_m": 0.0, "acceleration_g": 0.3,
                    "frequency_hz": 35.0, "phase_rad": 0.0, "duration_s": 1.0, "ramp_s": 0.2,
                    **(vibration or {}), **values}
        if not self.vibrate_server_ready(timeout):
            raise TimeoutError("action vibration_planner/vibrate not available")
        return self.send_goal("vibration_planner/vibrate", goal_message(settings), timeout)

    def plan_path(self, *waypoints, speed_scale: float = 0.0, timeout: float = 20.0):
        """Kinematics' PlanPath answer for ``waypoints`` (poses (6,), m, rad, base; one: from the pose
        estimate): outcome, failing_waypoint, failing_time_s, path, duration_s."""
        from rclpy.time import Time

        from stewart_vibration.nodes.message_conversions import pose_stamped
        from stewart_vibration_interfaces.srv import PlanPath

        request = PlanPath.Request(waypoints=[pose_stamped(p, Time().to_msg()) for p in waypoints],
                                   speed_scale=float(speed_scale))
        return self.call(PlanPath, "kinematics/plan_path", request, timeout)

    def start_recording(self, name: str = "", recorder: str = "/mcap_recorder"):
        """The recorder's StartRecording answer (outcome, path)."""
        from stewart_vibration_interfaces.srv import StartRecording

        return self.call(StartRecording, f"{recorder}/start", StartRecording.Request(name=name))

    def stop_recording(self, recorder: str = "/mcap_recorder"):
        """The recorder's StopRecording answer (outcome, path, messages, bytes)."""
        from stewart_vibration_interfaces.srv import StopRecording

        return self.call(StopRecording, f"{recorder}/stop", StopRecording.Request())

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()


@contextmanager
def node_under_test(name: str, module: str, domain: int, log_dir, args=(), pythonpath=None):
    """(NodeProcess, RosTestClient): ``python -m module args`` on ``domain`` (``pythonpath``: a directory put
    first on PYTHONPATH), stopped and checked on exit."""
    env = ros_environment(domain)
    if pythonpath is not None:
        env["PYTHONPATH"] = os.pathsep.join(p for p in (str(pythonpath), env.get("PYTHONPATH", "")) if p)
    proc = start_python_module(name, module, list(args), env, log_dir)
    client = RosTestClient()
    try:
        yield proc, client
    finally:
        client.close()
        assert proc.stop() is not None


__all__ = ["RosTestClient", "node_under_test", "rclpy"]


PLANNER_NOT_READY = ("NOT_READY", "CLOCK_NOT_RUNNING")  # the outcomes of a goal sent before the inputs arrive
