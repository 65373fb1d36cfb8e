"""Service calls and action goals that survive a lost answer.

Fast DDS can drop a service's response: the server sends it before it has matched the reply reader of a
client it has just discovered (it waits 100 ms for that, then gives up with "client will not receive
response"; ros2/rclc#390, ros2/rmw_fastrtps#706). ``wait_for_service`` only sees the client's own side, so
the first call of a fresh client on a busy machine can go unanswered although the service ran. Three rules:

- keep one client per service (``ServiceClients``): after the first call its reply reader stays matched;
- ask an idempotent service again after RESEND_AFTER_S without an answer (``answer_with_resend``);
- never send a lifecycle transition twice: a lost answer to one is recovered from the node's state
  (``transition_lifecycle``);
- never send an action goal twice: a lost answer to one is recovered from the action's status topic, which
  lists every goal the server accepted (``GoalAcceptances``, ``send_goal_recovering``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from uuid import uuid4

from action_msgs.msg import GoalStatusArray
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState
from unique_identifier_msgs.msg import UUID

# services that can be asked twice without changing anything: a client sends the request again after
# RESEND_AFTER_S without an answer (CI once waited 20 s for vibration_planner/set_parameters, and once for
# hardware_emulator/get_state, answers lost right after discovery)
IDEMPOTENT_SERVICES = ("/set_parameters", "/get_parameters", "/describe_parameters", "/list_parameters",
                       "/plan_path", "/get_state", "/get_available_states", "/get_available_transitions",
                       "/_action/cancel_goal")  # cancelling every goal again cancels nothing more
RESEND_AFTER_S = 5.0

# the primary state a lifecycle transition ends in when it succeeds (lifecycle_msgs/State labels)
TRANSITION_GOALS = {
    Transition.TRANSITION_CONFIGURE: "inactive",
    Transition.TRANSITION_CLEANUP: "unconfigured",
    Transition.TRANSITION_ACTIVATE: "active",
    Transition.TRANSITION_DEACTIVATE: "inactive",
    Transition.TRANSITION_UNCONFIGURED_SHUTDOWN: "finalized",
    Transition.TRANSITION_INACTIVE_SHUTDOWN: "finalized",
    Transition.TRANSITION_ACTIVE_SHUTDOWN: "finalized",
}

Wait = Callable[[Callable[[], bool], float], bool]


class ServiceClients:
    """One rclpy Client per service name of ``node``, created on first use and kept."""

    def __init__(self, node):
        self.node = node
        self._clients: dict[str, object] = {}

    def get(self, srv_type, name: str):
        """The kept Client of service ``name`` (created with ``srv_type`` the first time)."""
        if name not in self._clients:
            self._clients[name] = self.node.create_client(srv_type, name)
        return self._clients[name]


def answer_with_resend(client, name: str, request, timeout: float, wait: Wait):
    """The answer of service ``name`` to ``request`` through ``client`` (an rclpy Client whose service is
    ready), or None after ``timeout`` (wall s). ``wait(predicate, seconds) -> bool`` spins until
    ``predicate()`` or ``seconds`` pass. A request to one of IDEMPOTENT_SERVICES is sent again every
    RESEND_AFTER_S without an answer; any other is sent once."""
    deadline = time.monotonic() + timeout
    resend = name.endswith(IDEMPOTENT_SERVICES)
    while True:
        future = client.call_async(request)
        left = deadline - time.monotonic()
        if wait(future.done, min(left, RESEND_AFTER_S) if resend else left):
            return future.result()
        client.remove_pending_request(future)
        if not resend or time.monotonic() >= deadline:
            return None


def transition_lifecycle(client, transition_id: int, timeout: float, wait: Wait,
                         state_label: Callable[[], str | None]) -> bool | None:
    """Ask a lifecycle node for transition ``transition_id`` through ``client`` (its ready change_state
    Client). Returns the node's answer (True: made, False: refused), or None when there is neither an
    answer nor the goal state after ``timeout`` (wall s). The request is sent once; after each
    RESEND_AFTER_S without an answer ``state_label()`` (the node's get_state label, or None) is asked, and
    the transition's goal state there counts as made (its answer was lost)."""
    request = ChangeState.Request()
    request.transition.id = transition_id
    goal = TRANSITION_GOALS[transition_id]
    deadline = time.monotonic() + timeout
    future = client.call_async(request)
    while True:
        if wait(future.done, max(min(deadline - time.monotonic(), RESEND_AFTER_S), 0.0)):
            return bool(future.result().success)
        if state_label() == goal:
            client.remove_pending_request(future)
            return True
        if time.monotonic() >= deadline:
            client.remove_pending_request(future)
            return None


class GoalAcceptances:
    """The goals the action server ``action_name`` accepted, as its status topic lists them (kept for as long
    as the server keeps their results), for one node."""

    def __init__(self, node, action_name: str):
        from rclpy.qos import qos_profile_action_status_default

        self._accepted: set[bytes] = set()
        self._waiting: dict[bytes, Callable[[], None]] = {}
        self._sub = node.create_subscription(GoalStatusArray, f"{action_name}/_action/status", self._on_status,
                                             qos_profile_action_status_default)

    def _on_status(self, msg) -> None:
        listed = {bytes(s.goal_info.goal_id.uuid) for s in msg.status_list}
        self._accepted |= listed
        for goal in listed & self._waiting.keys():
            self._waiting.pop(goal)()

    def accepted(self, goal_id) -> bool:
        """Whether the server has listed the goal ``goal_id`` (unique_identifier_msgs/UUID) as accepted."""
        return bytes(goal_id.uuid) in self._accepted

    def when_accepted(self, goal_id, callback: Callable[[], None]) -> None:
        """Call ``callback()`` once the server lists ``goal_id`` (at once if it has)."""
        if self.accepted(goal_id):
            callback()
        else:
            self._waiting[bytes(goal_id.uuid)] = callback

    def forget(self, goal_id) -> None:
        """Stop waiting for ``goal_id``."""
        self._waiting.pop(bytes(goal_id.uuid), None)


def send_goal_recovering_async(action_client, goal, acceptances: GoalAcceptances, feedback_callback=None):
    """Send ``goal`` once through ``action_client`` (rclpy ActionClient, server ready). Returns an rclpy
    Future of its ClientGoalHandle: the server's answer, or, when ``acceptances`` (of the same action) lists
    the goal first, a handle marked accepted (the answer may have been lost), through which the result is
    asked as usual. The Future has ``goal_id`` (unique_identifier_msgs/UUID)."""
    from rclpy.action.client import ClientGoalHandle
    from rclpy.task import Future

    goal_id = UUID(uuid=list(uuid4().bytes))
    handle: Future = Future()
    handle.goal_id = goal_id  # type: ignore[attr-defined]

    def answered(sent) -> None:
        acceptances.forget(goal_id)
        if handle.done():
            return
        if sent.exception() is not None:
            handle.set_exception(sent.exception())
        else:
            handle.set_result(sent.result())

    def listed() -> None:
        if not handle.done():
            response = action_client._action_type.Impl.SendGoalService.Response(accepted=True)
            handle.set_result(ClientGoalHandle(action_client, goal_id, response))

    sent = action_client.send_goal_async(goal, feedback_callback=feedback_callback, goal_uuid=goal_id)
    sent.add_done_callback(answered)
    acceptances.when_accepted(goal_id, listed)
    return handle


def send_goal_recovering(action_client, goal, acceptances: GoalAcceptances, timeout: float, wait: Wait,
                         feedback_callback=None):
    """``send_goal_recovering_async``, waited for: the goal's ClientGoalHandle, or None when neither the
    server's answer nor its status listed the goal within ``timeout`` (wall s)."""
    handle = send_goal_recovering_async(action_client, goal, acceptances, feedback_callback)
    if wait(handle.done, timeout):
        return handle.result()
    acceptances.forget(handle.goal_id)
    return None


__all__ = ["IDEMPOTENT_SERVICES", "GoalAcceptances", "send_goal_recovering",
           "send_goal_recovering_async", "RESEND_AFTER_S", "TRANSITION_GOALS", "ServiceClients", "answer_with_resend",
           "transition_lifecycle"]
