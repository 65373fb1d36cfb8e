"""nodes.common.answer_with_resend: a request to an idempotent service whose answer is lost is sent
again; any other request is sent once (rclpy Futures; the lost answer is staged, DDS cannot lose one on
purpose)."""

from __future__ import annotations

import time

import pytest
from rclpy.task import Future

from stewart_vibration.nodes import common


class LossyClient:
    """Answers request k (1-based) only if k is in ``answered``; records what was sent and abandoned."""

    def __init__(self, answered=()):
        self.answered = set(answered)
        self.sent, self.removed = [], []

    def call_async(self, request):
        self.sent.append(request)
        future = Future()
        if len(self.sent) in self.answered:
            future.set_result(f"answer to #{len(self.sent)}")
        return future

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
