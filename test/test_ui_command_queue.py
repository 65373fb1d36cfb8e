"""The planning page's commands on their way (ui/command_queue.py) with fake futures and a stepped clock: e-stops
before every command, service calls answered once or refused after 10 s, and the e-stop's fan-out (one call at
a time, sent again every second, given up after 10 s, later e-stops answered by a call of their own)."""

from __future__ import annotations

from types import SimpleNamespace

from stewart_vibration.errors import InvalidInputError
from stewart_vibration.ui.command_queue import (
    CALL_TIMEOUT_S,
    ESTOP_DISCOVERY_S,
    ESTOP_RESEND_S,
    CommandInbox,
    EstopFanOut,
    ServiceCalls,
)
from stewart_vibration.ui.suite_status import EventLog

SERVICE = "/stewart/hardware_emulator/emergency_stop"


class FakeFuture:
    """An rclpy Future as the queue uses it: done by ``answer`` or ``fail``, its callbacks run then."""

    def __init__(self):
        self.callbacks, self.response, self.error = [], None, None

    def add_done_callback(self, callback):
        self.callbacks.append(callback)

    def cancelled(self):
        return False

    def exception(self):
        return self.error

    def result(self):
        return self.response

    def answer(self, response):
        self.response = response
        for callback in self.callbacks:
            callback(self)

    def fail(self, error):
        self.error = error
        for callback in self.callbacks:
            callback(self)


def trigger(success=True, message="emergency stop latched"):
    return SimpleNamespace(success=success, message=message)


def test_e_stops_go_before_every_command():
    inbox, order = CommandInbox(), []

    def send_estops():
        order.extend(f"estop {len(r)}" for r in [inbox.take_estops()] if r)

    def run(cmd, args, reply):
        order.append(cmd)
        if cmd == "move":
            inbox.put("estop", {}, None)  # pressed while the move was being sent

    inbox.put("move", {}, None)
    inbox.put("estop", {}, None)
    inbox.put("estop", {}, None)
    inbox.put("start", {}, None)
    inbox.run(send_estops, run)
    assert order == ["estop 2", "move", "estop 1", "start"]
    inbox.run(send_estops, run)  # nothing queued: e-stops are still sent
    assert order[-1] == "start"


def calls():
    logged = []
    return ServiceCalls(logged.append), logged


def test_a_call_is_answered_once_by_its_answer_or_its_failure():
    service_calls, logged = calls()
    replies, future = [], FakeFuture()
    service_calls.call("/x/reset", True, lambda: future, lambda r: replies.append({"ok": r.success}), replies.append,
                       now=0.0)
    assert len(service_calls.pending) == 1
    future.answer(trigger())
    assert replies == [{"ok": True}] and service_calls.pending == []
    failed = FakeFuture()
    service_calls.call("/x/reset", True, lambda: failed, replies.append, replies.append, now=0.0)
    failed.fail(RuntimeError("gone"))
    assert replies[-1] == {"ok": False, "refused_by": "planning_ui", "message": "/x/reset failed: gone"}
    service_calls.call("/x/reset", False, lambda: FakeFuture(), replies.append, replies.append, now=0.0)
    assert replies[-1]["message"] == "service /x/reset is not available (is its node running?)"
    assert logged == []


def test_an_answer_that_cannot_be_handled_is_refused_and_a_bug_logged():
    service_calls, logged = calls()
    replies, futures = [], [FakeFuture(), FakeFuture()]

    def refuse(response):
        raise InvalidInputError("path of 0 waypoints")

    def crash(response):
        raise KeyError("poses")

    service_calls.call("/k/plan_path", True, lambda: futures[0], refuse, replies.append, now=0.0)
    service_calls.call("/k/plan_path", True, lambda: futures[1], crash, replies.append, now=0.0)
    futures[0].answer(object())
    futures[1].answer(object())
    assert [r["message"] for r in replies] == ["InvalidInputError: path of 0 waypoints", "internal error: 'poses'"]
    assert logged == ["answer of /k/plan_path not handled: KeyError: 'poses'"]


def test_a_call_without_an_answer_is_refused_after_its_time_out():
    service_calls, _ = calls()
    replies = []
    service_calls.call("/p/get", True, FakeFuture, replies.append, replies.append, now=100.0)
    service_calls.expire(100.0 + CALL_TIMEOUT_S)
    assert replies == []
    service_calls.expire(100.0 + CALL_TIMEOUT_S + 0.01)
    assert replies == [{"ok": False, "refused_by": "planning_ui", "message": "no answer from /p/get within 10.0 s"}]
    service_calls.expire(200.0)
    assert len(replies) == 1 and service_calls.pending == []


class EstopService:
    """The emergency_stop service: every send is a new future; ``forgotten``: the sends dropped."""

    def __init__(self, ready=True):
        self.ready, self.sent, self.forgotten = ready, [], []
        self.now = 0.0

    def fan_out(self):
        events = EventLog(wall_clock=lambda: 0.0)
        fan = EstopFanOut(SERVICE, lambda: self.ready, self.send, self.forgotten.append, events, lambda: self.now)
        return fan, events

    def send(self):
        self.sent.append(FakeFuture())
        return self.sent[-1]


def test_an_unanswered_e_stop_is_sent_again_every_second_and_the_latest_send_answers():
    service, replies = EstopService(), []
    fan, events = service.fan_out()
    fan.tick([replies.append])
    assert len(service.sent) == 1 and [e["text"] for e in events.view()] == ["emergency stop requested from the page"]
    service.now = ESTOP_RESEND_S - 0.01
    fan.tick([])
    assert len(service.sent) == 1
    service.now = ESTOP_RESEND_S
    fan.tick([])
    assert len(service.sent) == 2 and service.forgotten == [service.sent[0]]
    service.sent[0].answer(trigger())  # the first send's late answer: that send was given up
    assert replies == []
    service.sent[1].answer(trigger())
    assert replies == [{"ok": True, "message": "emergency stop latched"}] and fan.call is None


def test_e_stops_during_a_call_are_answered_by_a_call_sent_after_them():
    service, first, later = EstopService(), [], []
    fan, events = service.fan_out()
    fan.tick([first.append])
    fan.tick([later.append, later.append])  # two more while the first call is in flight: one call for both
    assert len(service.sent) == 1
    service.sent[0].answer(trigger())
    assert first == [{"ok": True, "message": "emergency stop latched"}] and later == []
    assert len(service.sent) == 2 and len(events.view()) == 2
    service.sent[1].answer(trigger(False, "not latched: the units are off"))
    assert later == [{"ok": False, "message": "not latched: the units are off",
                      "refused_by": "hardware_emulator"}] * 2


def test_an_e_stop_is_given_up_after_the_time_out_and_refused_when_there_is_no_server():
    service, replies = EstopService(), []
    fan, _ = service.fan_out()
    fan.tick([replies.append])
    service.now = 0.5
    fan.tick([replies.append])
    for k in range(1, 10):
        service.now = float(k)
        fan.tick([])
    assert len(service.sent) == 10 and replies == []
    service.now = CALL_TIMEOUT_S
    fan.tick([])
    assert replies == [{"ok": False, "refused_by": "planning_ui",
                        "message": f"no answer from {SERVICE} within 10.0 s"}] * 2
    assert fan.call is None and service.forgotten[-1] is service.sent[-1]
    service.ready = False
    fan.tick([replies.append])  # no server seen yet: it waits for one to be discovered, then gives up
    service.now += ESTOP_DISCOVERY_S - 0.01
    fan.tick([])
    assert len(replies) == 2 and fan.call is None and len(service.sent) == 10
    service.now += 0.01
    fan.tick([])
    assert replies[-1]["message"] == f"service {SERVICE} is not available (is its node running?)"
    assert fan.call is None and len(service.sent) == 10 and fan.waiting is None


def test_an_e_stop_pressed_before_its_service_is_discovered_is_sent_once_it_is():
    """A page can press e-stop while the UI's client has not matched the emulator's service yet: the request
    waits for the server instead of being refused (a request sent before the match would be lost)."""
    service, replies = EstopService(ready=False), []
    fan, events = service.fan_out()
    fan.tick([replies.append])
    fan.tick([replies.append])  # a second press while waiting: answered by the same call
    assert service.sent == [] and replies == []
    service.now, service.ready = ESTOP_DISCOVERY_S - 0.5, True
    fan.tick([])
    assert len(service.sent) == 1 and len(events.view()) == 1
    service.sent[0].answer(trigger())
    assert replies == [{"ok": True, "message": "emergency stop latched"}] * 2 and fan.waiting is None


def test_a_failed_e_stop_call_says_why():
    service, replies = EstopService(), []
    fan, _ = service.fan_out()
    fan.tick([replies.append])
    service.sent[0].fail(RuntimeError("context shut down"))
    assert replies == [{"ok": False, "refused_by": "planning_ui",
                        "message": "emergency_stop failed: context shut down"}]
