"""nodes.service_calls: a request to an idempotent service whose answer is lost is sent again; any other
request is sent once; a lifecycle transition whose answer is lost is recovered from the node's state, never
sent twice (rclpy Futures; the lost answer is staged, DDS cannot lose one on purpose)."""

from __future__ import annotations

import time
import types

import pytest
from lifecycle_msgs.msg import Transition
from rclpy.task import Future

from stewart_vibration.nodes import service_calls as common


class LossyClient:
    """Answers request k (1-based) only if k is in ``answered``; records what was sent and abandoned."""

    def __init__(self, answered=()):
        self.answered = set(answered)
        self.sent, self.removed = [], []

    def call_async(self, request):
        self.sent.append(request)
        future = Future()
        if len(self.sent) in self.answered:
            future.set_result(self.answer(len(self.sent)))
        return future

    def answer(self, k):
        return f"answer to #{k}"

    def remove_pending_request(self, future):
        self.removed.append(future)


def wait(predicate, seconds):
    """Spin stand-in: the answer either is there or does not come within ``seconds``."""
    if predicate():
        return True
    time.sleep(seconds)
    return bool(predicate())


@pytest.fixture(autouse=True)
def quick_resend(monkeypatch):
    monkeypatch.setattr(common, "RESEND_AFTER_S", 0.02)


def test_a_lost_answer_to_an_idempotent_request_is_asked_again():
    client = LossyClient(answered={2})
    assert common.answer_with_resend(client, "/stewart/vibration_planner/set_parameters", "req", 5.0, wait) \
        == "answer to #2"
    assert client.sent == ["req", "req"] and len(client.removed) == 1


def test_a_request_that_changes_state_is_sent_once():
    client = LossyClient(answered={2})
    assert common.answer_with_resend(client, "/stewart/vibration_planner/start", "req", 0.1, wait) is None
    assert client.sent == ["req"]


def test_an_idempotent_service_that_never_answers_gives_up_at_the_timeout():
    client = LossyClient()
    start = time.monotonic()
    assert common.answer_with_resend(client, "/stewart/kinematics/plan_path", "req", 0.2, wait) is None
    assert 0.2 <= time.monotonic() - start < 1.0
    assert 5 <= len(client.sent) <= 11 and len(client.removed) == len(client.sent)


def test_an_answer_in_time_is_not_asked_again():
    client = LossyClient(answered={1})
    assert common.answer_with_resend(client, "/x/get_parameters", "req", 1.0, wait) == "answer to #1"
    assert client.sent == ["req"] and not client.removed


class LossyLifecycleNode(LossyClient):
    """A lifecycle node's change_state: ``made`` is whether it makes the transition (its answer's
    ``success``); the node's state label is ``state`` before and the transition's goal after a request."""

    def __init__(self, answered=(), made=True, state="unconfigured"):
        super().__init__(answered)
        self.made, self.state, self.asked = made, state, 0

    def answer(self, k):
        return types.SimpleNamespace(success=self.made)

    def call_async(self, request):
        if self.made:
            self.state = common.TRANSITION_GOALS[request.transition.id]
        return super().call_async(request)

    def state_label(self):
        self.asked += 1
        return self.state


def test_a_transition_whose_answer_is_lost_is_recovered_from_the_nodes_state_not_sent_again():
    node = LossyLifecycleNode(answered=())
    made = common.transition_lifecycle(node, Transition.TRANSITION_CONFIGURE, 5.0, wait, node.state_label)
    assert made is True and node.state == "inactive"
    assert len(node.sent) == 1 and node.asked == 1 and len(node.removed) == 1


def test_an_answered_transition_is_its_answer_and_the_state_is_not_asked():
    for made in (True, False):
        node = LossyLifecycleNode(answered={1}, made=made, state="inactive")
        assert common.transition_lifecycle(node, Transition.TRANSITION_ACTIVATE, 5.0, wait, node.state_label) is made
        assert len(node.sent) == 1 and node.asked == 0


def test_a_lost_transition_the_node_did_not_make_times_out_without_a_second_request():
    node = LossyLifecycleNode(answered=(), made=False, state="inactive")
    start = time.monotonic()
    assert common.transition_lifecycle(node, Transition.TRANSITION_ACTIVATE, 0.2, wait, node.state_label) is None
    assert 0.2 <= time.monotonic() - start < 1.0
    assert len(node.sent) == 1 and node.asked >= 5 and len(node.removed) == 1
