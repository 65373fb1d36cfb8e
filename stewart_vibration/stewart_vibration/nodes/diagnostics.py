"""A node's health on /diagnostics and what it refuses: one DiagnosticStatus republished on wall time and on
change (STALE while a watched input is missing), a rejected input reported (WARN) and logged rate-limited,
and malformed messages counted per input. Periods and timeouts in wall s."""

from __future__ import annotations

import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.clock import Clock, ClockType
from rclpy.publisher import Publisher

from ..errors import MalformedMessageError
from ..messages.malformed import MalformedCounter
from ..rate_limit import RepeatedLine

OK, WARN, ERROR, STALE = DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR, DiagnosticStatus.STALE


class Diagnostics:
    """One DiagnosticStatus on /diagnostics, republished every ``period_s`` of wall time (so it goes on when
    /clock stops) and on change. Inputs registered with ``watch`` are checked on wall time: one that has not
    arrived within its timeout turns the status STALE, naming what is missing, until it arrives again."""

    values: dict[str, str]

    def __init__(self, node, name: str, period_s: float = 1.0):
        self._node = node
        self._name = f"{node.get_name()}: {name}"
        self._pub = node.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.level, self.message, self.values = OK, "starting", {}
        self._watched: dict[str, tuple[float, float, str]] = {}  # input -> (timeout s, last seen, hint)
        self._stale: tuple = ()
        self._outputs: dict[str, Publisher] = {}  # output name -> its publisher (matched readers are reported)
        self._started = time.monotonic()
        self.rejection_lines = RepeatedLine()  # the node's refusal log: one repeated line a second, with a count
        node.create_timer(period_s, self.publish, clock=Clock(clock_type=ClockType.STEADY_TIME))
        node.create_timer(0.25, self._check_inputs, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def watch(self, name: str, timeout_s: float, hint: str = "") -> None:
        """Expect input ``name`` at least every ``timeout_s`` (wall s) once it has started or the node has run
        that long; ``hint`` says which node provides it."""
        self._watched[name] = (timeout_s, self._started, hint)

    def report_readers(self, name: str, publisher: Publisher) -> None:
        """Report how many subscriptions ``publisher`` (output ``name``) has matched, as the value
        "matched_subscribers <name>" of every status: who really receives it (a reader the graph shows
        may not be matched yet)."""
        self._outputs[name] = publisher

    def seen(self, name: str) -> None:
        """Input ``name`` arrived now."""
        timeout, _, hint = self._watched[name]
        self._watched[name] = (timeout, time.monotonic(), hint)

    def _check_inputs(self) -> None:
        now = time.monotonic()
        stale = tuple(f"no {name} for {now - last:.1f} s{f' ({hint})' if hint else ''}"
                      for name, (timeout, last, hint) in self._watched.items() if now - last > timeout)
        if bool(stale) != bool(self._stale) or (stale and self._stale and len(stale) != len(self._stale)):
            self._stale = stale
            self.publish()
        self._stale = stale

    def set(self, level: bytes, message: str, **values) -> None:
        changed = (level, message) != (self.level, self.message)
        self.level, self.message = level, message
        self.values.update({k: str(v) for k, v in values.items()})
        if changed:
            self.publish()

    def publish(self) -> None:
        for name, publisher in self._outputs.items():
            self.values[f"matched_subscribers {name}"] = str(publisher.get_subscription_count())
        level, message = self.level, self.message
        if self._stale:  # an ERROR of the node's own stays ERROR; the missing inputs are named either way
            level = ERROR if level == ERROR else STALE
            message = f"stale: {'; '.join(self._stale)}; {message}"
        status = DiagnosticStatus(
            level=level,
            name=self._name,
            message=message,
            hardware_id="stewart_vibration",
            values=[KeyValue(key=k, value=v) for k, v in sorted(self.values.items())],
        )
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = self._node.get_clock().now().to_msg()
        self._pub.publish(msg)


def reject(node, diagnostics: Diagnostics, what: str, reason: str, log: bool = True) -> None:
    """Log a rejected input with its reason (unless ``log`` is False: the caller logs, rate-limited) and report
    it on /diagnostics (WARN)."""
    if log:
        line = diagnostics.rejection_lines.line(f"rejected {what}: {reason}", time.monotonic())
        if line is not None:
            node.get_logger().warning(line)
    diagnostics.set(WARN, f"rejected {what}: {reason}", last_rejection=reason)


class MalformedInputs:
    """Malformed messages a node ignored (it goes on with its last good state): counted per input
    (messages.malformed.MalformedCounter), logged -- the first of each reason, then at most one line per
    second per input -- and reported on /diagnostics as ``malformed <input>`` counts (``diagnostics`` None:
    logged only, e.g. the runner's client)."""

    LOG_CHARACTERS = 300  # a logged reason is cut here (a hostile message can be megabytes)

    def __init__(self, node, diagnostics: Diagnostics | None):
        self.node, self.diagnostics = node, diagnostics
        self.counter = MalformedCounter()

    def read(self, input_name: str, parse, data):
        """``parse(data)``, or None after counting the MalformedMessageError it raised for ``input_name``."""
        try:
            return parse(data)
        except MalformedMessageError as exc:
            self.refuse(input_name, exc)
            return None

    def refuse(self, input_name: str, error: Exception, count: int = 1) -> None:
        """``count`` malformed messages of ``input_name`` (topic or service), ``error`` saying why."""
        # a typed core error (e.g. a trajectory's InvalidInputError) names its fault in its first words
        reason = error.reason if isinstance(error, MalformedMessageError) else f"{type(error).__name__} {error}"[:48]
        text = str(error)[:self.LOG_CHARACTERS]
        log = self.counter.record(input_name, reason, text, time.monotonic(), count)
        if self.diagnostics is not None:
            self.diagnostics.values.update(self.counter.values())
        if log:
            self.node.get_logger().warning(f"ignored malformed {input_name} ({self.counter.counts[input_name]} so "
                                           f"far): {text}")
            if self.diagnostics is not None:
                self.diagnostics.publish()


__all__ = [
    "OK",
    "WARN",
    "ERROR",
    "STALE",
    "Diagnostics",
    "reject",
    "MalformedInputs",
]
