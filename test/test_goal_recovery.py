"""nodes.service_calls.send_goal_recovering over real rclpy and DDS: a goal whose answer is lost is recovered
from the action's status topic (never sent twice) and its result is asked as usual; a refusal is the
server's answer; no server is None at the timeout. The lost answer is staged by dropping the answer future
on the client side: DDS cannot lose one on purpose."""

from __future__ import annotations

import time

import pytest
from rclpy.action import ActionClient, ActionServer, GoalResponse
from rclpy.node import Node
from rclpy.task import Future
from ros_client import RosTestClient

from stewart_vibration.nodes.service_calls import GoalAcceptances, send_goal_recovering
from stewart_vibration_interfaces.action import Vibrate

pytestmark = pytest.mark.integration

ACTION = "recovery_check/vibrate"


class AnswerLost:
    """A real ActionClient whose goals go out over DDS but whose answers never reach the caller."""

    def __init__(self, client: ActionClient):
        self._client = client
        self.sent = 0

    def send_goal_async(self, goal, **kwargs):
        self.sent += 1
        self._client.send_goal_async(goal, **kwargs)
        return Future()

    def __getattr__(self, name):
        return getattr(self._client, name)


@pytest.fixture
def served(ros_domain):
    """(test client, the goals the server executed) with an in-process Vibrate server that accepts goals of
    positive duration, refuses others, and ends each with outcome code 1 and its duration in the message."""
    client = RosTestClient("goal_recovery_client")
    server_node = Node("goal_recovery_server", context=client.context)
    executed = []

    def execute(handle):
        executed.append(bytes(handle.goal_id.uuid))
        handle.succeed()
        result = Vibrate.Result()
        result.outcome.code = 1
        result.outcome.message = f"ran {handle.request.duration_s:.1f} s"
        return result

    server = ActionServer(server_node, Vibrate, ACTION, execute_callback=execute,
                          goal_callback=lambda g: GoalResponse.ACCEPT if g.duration_s > 0 else GoalResponse.REJECT)
    client.executor.add_node(server_node)
    action_client = ActionClient(client.node, Vibrate, ACTION)
    assert client.spin_until(action_client.server_is_ready, 20.0)
    client.spin_for(0.5)
    yield client, action_client, executed
    server.destroy()
    server_node.destroy_node()
    client.close()


def test_a_goal_whose_answer_is_lost_is_recovered_from_the_status_and_its_result_arrives(served):
    client, action_client, executed = served
    lossy = AnswerLost(action_client)
    handle = send_goal_recovering(lossy, Vibrate.Goal(duration_s=2.5), GoalAcceptances(client.node, ACTION), 10.0,
                                  client.spin_until)
    assert handle is not None and handle.accepted and lossy.sent == 1
    result = handle.get_result_async()
    assert client.spin_until(result.done, 10.0)
    assert result.result().result.outcome.code == 1 and result.result().result.outcome.message == "ran 2.5 s"
    assert executed == [bytes(handle.goal_id.uuid)]


def test_an_answered_goal_is_the_servers_answer(served):
    client, action_client, executed = served
    acceptances = GoalAcceptances(client.node, ACTION)
    refused = send_goal_recovering(action_client, Vibrate.Goal(duration_s=0.0), acceptances, 10.0, client.spin_until)
    assert refused is not None and not refused.accepted and executed == []
    taken = send_goal_recovering(action_client, Vibrate.Goal(duration_s=1.0), acceptances, 10.0, client.spin_until)
    assert taken is not None and taken.accepted
    assert client.spin_until(lambda: executed, 10.0) and executed == [bytes(taken.goal_id.uuid)]


def test_a_lost_refusal_is_none_at_the_timeout_and_not_sent_again(served):
    client, action_client, executed = served
    lossy = AnswerLost(action_client)
    start = time.monotonic()
    handle = send_goal_recovering(lossy, Vibrate.Goal(duration_s=0.0), GoalAcceptances(client.node, ACTION), 1.0,
                                  client.spin_until)
    assert handle is None and lossy.sent == 1 and executed == []
    assert 1.0 <= time.monotonic() - start < 3.0
