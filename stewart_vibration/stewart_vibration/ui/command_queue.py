"""The planning page's commands on their way to the suite (pure, no rclpy): the queue the web server's thread
fills and the node's executor empties, the service calls in flight with their time-out, and the emergency
stop's fan-out (first, coalesced, sent again until answered).

A call's ``future`` is anything with ``add_done_callback``, ``cancelled``, ``exception`` and ``result`` (an
rclpy Future in the node); a ``reply`` sends one answer dict to the page that asked. Times are s of the node's
monotonic clock.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ..errors import StewartError
from .suite_status import Event, EventLog

CALL_TIMEOUT_S = 10.0
ESTOP_RESEND_S = 1.0  # an unanswered e-stop call is sent again after this (its answer may be lost; it is idempotent)
# how long an e-stop waits for its service to be discovered before it is answered as unavailable: a page can press
# it while the UI's client has not yet matched the emulator's service, and a request sent before that is lost
ESTOP_DISCOVERY_S = 3.0
ESTOP = "estop"

Reply = Callable[[dict], None]


def refusal(message: str, refused_by: str = "planning_ui") -> dict:
    """The answer to a command that was not done, and who refused it."""
    return {"ok": False, "refused_by": refused_by, "message": message}


def unavailable(service: str) -> dict:
    """The answer when ``service`` has no server (nothing was sent)."""
    return refusal(f"service {service} is not available (is its node running?)")


def no_answer(service: str) -> dict:
    """The answer when ``service`` did not answer within CALL_TIMEOUT_S."""
    return refusal(f"no answer from {service} within {CALL_TIMEOUT_S} s")


def trigger_reply(response, refused_by: str) -> dict:
    """The answer of a std_srvs/Trigger ``response`` (success, message); ``refused_by`` when it failed."""
    return {"ok": bool(response.success), "message": response.message,
            **({} if response.success else {"refused_by": refused_by})}


def answering_errors(run: Callable[[], None], reply: Reply, log_error: Callable[[str], None], what: str) -> None:
    """``run()``; a core error it raises is the page's answer, any other is logged as ``what`` and answered as an
    internal error (a bug must not kill the node: this runs in the executor)."""
    try:
        run()
    except StewartError as exc:
        reply(refusal(f"{type(exc).__name__}: {exc}"))
    except Exception as exc:  # noqa: BLE001 - the page says what failed
        log_error(f"{what}: {type(exc).__name__}: {exc}")
        reply(refusal(f"internal error: {exc}"))


class CommandInbox:
    """Commands from the pages (put from the server's thread), e-stops apart: they go before any command."""

    def __init__(self):
        self.lock = threading.Lock()
        self.commands: deque[tuple[str, dict, Reply]] = deque()
        self.estops: list[Reply] = []  # replies of e-stops not yet sent on

    def put(self, cmd: str, args: dict, reply: Reply) -> None:
        """A page's command ``cmd`` with its ``args``; ``reply`` answers it (from any thread)."""
        with self.lock:
            if cmd == ESTOP:  # never behind another command: sent first, coalesced
                self.estops.append(reply)
            else:
                self.commands.append((cmd, args, reply))

    def take_estops(self) -> list[Reply]:
        """The replies of the e-stops put since the last call (each once)."""
        with self.lock:
            replies, self.estops = self.estops, []
        return replies

    def run(self, send_estops: Callable[[], None], run_command: Callable[[str, dict, Reply], None]) -> None:
        """Run the queued commands in order, ``send_estops()`` first and again before each command (an e-stop that
        came meanwhile goes before the next one)."""
        send_estops()
        if not self.commands:
            return
        while True:
            send_estops()
            with self.lock:
                if not self.commands:
                    return
                cmd, args, reply = self.commands.popleft()
            run_command(cmd, args, reply)


@dataclass
class PendingCall:
    """A service call in flight: refused at ``deadline`` (s) unless ``future`` is done before."""

    deadline: float
    future: Any
    service: str
    reply: Reply


class ServiceCalls:
    """Service calls in flight, each answered once by ``done(response)`` or a failure, or refused after
    CALL_TIMEOUT_S. ``log_error``: where an answer that could not be handled is told."""

    def __init__(self, log_error: Callable[[str], None]):
        self.log_error = log_error
        self.pending: list[PendingCall] = []

    def call(self, service: str, ready: bool, send: Callable[[], Any], done: Callable[[Any], None], reply: Reply,
             now: float) -> None:
        """Call ``service`` (``send()`` returns the future) if it is ``ready``, else refuse at once."""
        if not ready:
            reply(unavailable(service))
            return
        future = send()
        self.pending.append(PendingCall(now + CALL_TIMEOUT_S, future, service, reply))

        def finished(f) -> None:
            self.pending[:] = [p for p in self.pending if p.future is not f]
            if f.cancelled() or f.exception() is not None:
                reply(refusal(f"{service} failed: {f.exception()}"))
                return
            answering_errors(lambda: done(f.result()), reply, self.log_error, f"answer of {service} not handled")

        future.add_done_callback(finished)

    def expire(self, now: float) -> None:
        """Refuse the calls past their deadline."""
        for call in [c for c in self.pending if c.deadline < now]:
            self.pending.remove(call)
            call.reply(no_answer(call.service))


@dataclass
class EstopCall:
    """One emergency_stop call: the future of its latest send, when that was sent and when the call is given
    up (s), the replies it answers and those of e-stops that came while it was in flight (answered by one more
    call after it, so each e-stop is answered by a call sent after it came)."""

    future: Any
    sent: float
    deadline: float
    replies: list[Reply]
    again: list[Reply] = field(default_factory=list)


class EstopFanOut:
    """The pages' e-stops: one call of ``service`` at a time (``send()`` returns its future; ``forget(future)``
    drops an earlier send), sent again every ESTOP_RESEND_S while unanswered (it is idempotent; an answer can
    be lost), failed after CALL_TIMEOUT_S. While the service is not yet discovered the e-stops wait for it, up to
    ESTOP_DISCOVERY_S, and are answered as unavailable after that. A reset between two e-stops cannot swallow the
    second."""

    def __init__(self, service: str, ready: Callable[[], bool], send: Callable[[], Any],
                 forget: Callable[[Any], None], events: EventLog, clock: Callable[[], float] = time.monotonic):
        self.service, self.ready, self.send, self.forget = service, ready, send, forget
        self.events, self.clock = events, clock
        self.call: EstopCall | None = None
        self.waiting: tuple[float, list[Reply]] | None = None  # (give up at (s), replies): no server seen yet

    def tick(self, replies: list[Reply]) -> None:
        """The e-stops that came since the last tick (their replies); resend or give up the call in flight."""
        if replies and self.call is not None:
            self.call.again.extend(replies)
        elif replies and self.waiting is not None:
            self.waiting[1].extend(replies)
        elif replies:
            self._requested(replies)
        if self.waiting is not None:
            self._send_when_ready()
        call = self.call
        if call is None:
            return
        now = self.clock()
        if now >= call.deadline:
            self.call = None
            self.forget(call.future)
            for reply in call.replies + call.again:
                reply(no_answer(self.service))
        elif now - call.sent >= ESTOP_RESEND_S:
            self.forget(call.future)
            call.future, call.sent = self.send(), now
            call.future.add_done_callback(self.answered)

    def _send_when_ready(self) -> None:
        """The waiting e-stops: one call once the service is discovered, or unavailable when it was not in time."""
        if self.waiting is None:
            return
        give_up, replies = self.waiting
        if self.ready():
            self.waiting = None
            now = self.clock()
            self.call = EstopCall(self.send(), now, now + CALL_TIMEOUT_S, replies)
            self.call.future.add_done_callback(self.answered)
        elif self.clock() >= give_up:
            self.waiting = None
            for reply in replies:
                reply(unavailable(self.service))

    def answered(self, future) -> None:
        """A send's future is done: its answer goes to the call's replies (an earlier send of a call sent again,
        or one given up, is ignored); e-stops that came meanwhile get a call of their own."""
        call = self.call
        if call is None or future is not call.future:
            return
        self.call = None
        if future.cancelled() or future.exception() is not None:
            result = refusal(f"emergency_stop failed: {future.exception()}")
        else:
            result = trigger_reply(future.result(), "hardware_emulator")
        for reply in call.replies:
            reply(result)
        if call.again:
            self._requested(call.again)
            self._send_when_ready()

    def _requested(self, replies: list[Reply]) -> None:
        """New e-stops with no call in flight: logged, and waiting for the service (``_send_when_ready``)."""
        self.events.add(Event("planning_ui", "emergency stop requested from the page", "ERROR"))
        self.waiting = (self.clock() + ESTOP_DISCOVERY_S, list(replies))
