"""What the planning page shows of the suite's health (pure): every node's /diagnostics status, the events log
and the MCAP file the recorder writes, with its run report's files.

The planning_ui node feeds it the checked statuses it reads (messages.status_values); times are s of the
node's monotonic clock (``now``) and wall-clock s since the epoch (an event's ``wall``, what the page prints).
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

from ..errors import MalformedMessageError
from ..messages.status_values import StatusMessage, recorder_files

LEVELS = {0: "OK", 1: "WARN", 2: "ERROR", 3: "STALE"}  # DiagnosticStatus levels as the page names them
EVENTS_KEPT = 30
MAX_NODE_STATUSES = 256  # distinct /diagnostics status names kept for the page (a spoofer could send millions)
RECORDER_NODE = "mcap_recorder"
REPORT_SUFFIXES = (".png", ".md", ".json")  # the run report's files the page links to


@dataclass(frozen=True)
class Event:
    """One line of the page's events log: who said it, what, and its level ("OK", "WARN", "ERROR")."""

    source: str
    text: str
    level: str = "WARN"


class EventLog:
    """The last EVENTS_KEPT events, numbered from 1 (the page shows each number once), stamped with
    ``wall_clock()`` (s since the epoch) when logged."""

    def __init__(self, wall_clock: Callable[[], float] = time.time, kept: int = EVENTS_KEPT):
        self.wall_clock = wall_clock
        self.entries: deque[dict] = deque(maxlen=kept)
        self.seq = 0

    def add(self, event: Event | None) -> None:
        """Log ``event`` (None: nothing happened worth a line)."""
        if event is None:
            return
        self.seq += 1
        self.entries.append({"seq": self.seq, "wall": self.wall_clock(), "source": event.source,
                             "level": event.level, "text": event.text})

    def extend(self, events: Iterable[Event]) -> None:
        """Log each of ``events`` in order."""
        for event in events:
            self.add(event)

    def view(self) -> list[dict]:
        """The kept events, oldest first: seq, wall, source, level, text."""
        return list(self.entries)


@dataclass(frozen=True)
class NodeStatus:
    """A node's latest /diagnostics status: ``level`` (0..3), message, values, and when it came (``seen``, s)."""

    level: int
    message: str
    values: Mapping[str, str]
    seen: float

    def view(self, name: str, now: float) -> dict:
        """The page's row of the status ``name``: level by name, message, age at ``now`` (s)."""
        return {"name": name, "level": LEVELS.get(self.level, str(self.level)), "message": self.message,
                "age_s": now - self.seen}


@dataclass
class RecorderFile:
    """The MCAP file the recorder writes ("recording") or wrote last ("finished"); "unknown" before it says."""

    path: str | None = None
    state: str = "unknown"

    def view(self) -> dict:
        """The page's view: path and state."""
        return {"path": self.path, "state": self.state}


def report_files(mcap_path: str | None) -> list[str]:
    """The run report's files (REPORT_SUFFIXES) in the ``report`` folder beside ``mcap_path``, sorted by name;
    none if there is no such folder or it cannot be read."""
    folder = Path(mcap_path).parent / "report" if mcap_path else None
    try:
        return sorted(p.name for p in folder.iterdir() if p.suffix in REPORT_SUFFIXES) \
            if folder is not None and folder.is_dir() else []
    except OSError:  # a path the recorder named that cannot be listed (gone, unreadable, too long)
        return []


class SuiteStatus:
    """The nodes' statuses by name (at most MAX_NODE_STATUSES), the events log and the recorder's file.
    ``own_name``: this node's own status name (its changes are no event: the page shows them already)."""

    def __init__(self, own_name: str, events: EventLog | None = None):
        self.own_name = own_name
        self.events = events or EventLog()
        self.nodes: dict[str, NodeStatus] = {}
        self.recorder = RecorderFile()
        self.report: list[str] = []  # the report's file names beside the recorder's file

    def on_diagnostics(self, statuses: Iterable[StatusMessage], now: float) -> list[MalformedMessageError]:
        """Take one /diagnostics message's checked statuses at ``now`` (s): a new or changed message at WARN or
        worse is an event; the recorder's status names its file. Returns what was refused (too many names, a
        recorder status without clean paths), for the node to count as malformed."""
        refused = []
        for status in statuses:
            if status.name not in self.nodes and len(self.nodes) >= MAX_NODE_STATUSES:
                refused.append(MalformedMessageError(
                    f"more than {MAX_NODE_STATUSES} status names; {status.name[:60]!r} ignored", field="name",
                    kind="length"))
                continue
            before = self.nodes.get(status.name)
            said_before = None if before is None else before.message
            self.nodes[status.name] = NodeStatus(status.level, status.message, dict(status.values), now)
            # news for the log when the status says something else than last time: the text is compared whole
            # with its own previous one, never searched for a meaning
            if said_before != status.message and status.level >= 1 and status.name != self.own_name:
                self.events.add(Event(status.node, status.message, LEVELS.get(status.level, "ERROR")))
            try:
                if status.node == RECORDER_NODE:  # the file being written (also for a page opened after it started)
                    self._follow_recorder(status)
            except MalformedMessageError as exc:
                refused.append(exc)
        return refused

    def _follow_recorder(self, status: StatusMessage) -> None:
        files = recorder_files(status)
        if files.path:
            path, state = files.path, "recording"
        elif files.last_file:
            path, state = files.last_file, "finished"
        else:
            return
        if (self.recorder.path, self.recorder.state) != (path, state):
            self.recorder = RecorderFile(path, state)
            self.list_report()

    def list_report(self) -> None:
        """Look again for the report beside the recorder's file (it is written after the run)."""
        self.report = report_files(self.recorder.path)

    def report_file(self, kind: str, name: str) -> Path | None:
        """The path of a report file the page may fetch (one listed), else None."""
        if kind != "report" or name not in self.report or not self.recorder.path:
            return None
        return Path(self.recorder.path).parent / "report" / name

    def nodes_view(self, now: float) -> list[dict]:
        """Every node's status row (NodeStatus.view) sorted by name."""
        return [status.view(name, now) for name, status in sorted(self.nodes.items())]
