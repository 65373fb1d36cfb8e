"""What the planning page shows of the suite (ui/suite_status.py) with stepped clocks: the events log (numbered,
stamped, the last 30 kept), the nodes' /diagnostics statuses (a new or changed message at WARN or worse is an
event, at most 256 names), and the recorder's file with the report files beside it."""

from __future__ import annotations

from pathlib import Path

from stewart_vibration.messages.status_values import StatusMessage
from stewart_vibration.ui.suite_status import MAX_NODE_STATUSES, Event, EventLog, SuiteStatus, report_files

OWN = "planning_ui: planning UI"


def status(name, message="ok", level=0, **values):
    return StatusMessage(level, name, message, "", values)


def suite():
    return SuiteStatus(OWN, EventLog(wall_clock=iter(range(100, 10_000)).__next__))


def test_the_events_log_numbers_stamps_and_keeps_the_last_thirty():
    log = EventLog(wall_clock=iter(range(100, 200)).__next__)
    log.add(None)  # nothing worth a line
    log.add(Event("kinematics", "move SUCCEEDED", "OK"))
    assert log.view() == [{"seq": 1, "wall": 100, "source": "kinematics", "level": "OK", "text": "move SUCCEEDED"}]
    log.extend(Event("n", f"e{i}") for i in range(2, 41))
    kept = log.view()
    assert [e["seq"] for e in kept] == list(range(11, 41)) and kept[-1]["wall"] == 139 and kept[0]["level"] == "WARN"


def test_a_status_is_an_event_when_it_is_new_or_changed_and_at_warn_or_worse():
    s = suite()
    assert s.on_diagnostics([status("kinematics: kinematics", "pose estimate stale", 1),
                             status("leg_force_estimator: estimator", "ok", 0),
                             status(OWN, "no planner", 2)], now=1.0) == []
    s.on_diagnostics([status("kinematics: kinematics", "pose estimate stale", 1)], now=2.0)  # unchanged
    s.on_diagnostics([status("kinematics: kinematics", "pose estimate stale", 2)], now=2.5)  # the same words
    s.on_diagnostics([status("kinematics: kinematics", "no joint states", 3)], now=3.0)
    assert [(e["source"], e["level"], e["text"]) for e in s.events.view()] == [
        ("kinematics", "WARN", "pose estimate stale"), ("kinematics", "STALE", "no joint states")]
    assert s.nodes_view(now=4.5) == [
        {"name": "kinematics: kinematics", "level": "STALE", "message": "no joint states", "age_s": 1.5},
        {"name": "leg_force_estimator: estimator", "level": "OK", "message": "ok", "age_s": 3.5},
        {"name": OWN, "level": "ERROR", "message": "no planner", "age_s": 3.5}]


def test_names_beyond_the_limit_are_refused_and_the_known_ones_still_followed():
    s = suite()
    refused = s.on_diagnostics([status(f"spoof: {i}") for i in range(MAX_NODE_STATUSES + 2)], now=1.0)
    assert len(s.nodes) == MAX_NODE_STATUSES and len(refused) == 2
    assert all(error.reason == "length name" for error in refused)
    assert s.on_diagnostics([status("spoof: 3", "changed", 1)], now=2.0) == []
    assert s.nodes["spoof: 3"].message == "changed"


def write_report(folder: Path) -> Path:
    (folder / "report").mkdir(parents=True)
    for name in ("b.png", "a.md", "c.json", "notes.txt"):
        (folder / "report" / name).write_text("x")
    return folder / "run.mcap"


def test_the_recorder_s_file_and_its_report_are_followed(tmp_path):
    s = suite()
    assert s.recorder.view() == {"path": None, "state": "unknown"}
    mcap = write_report(tmp_path / "run1")
    s.on_diagnostics([status("mcap_recorder: recorder", "recording", 0, path=str(mcap), last_file="")], now=1.0)
    assert s.recorder.view() == {"path": str(mcap), "state": "recording"}
    assert s.report == ["a.md", "b.png", "c.json"]  # sorted, only what the page links to
    assert s.report_file("report", "b.png") == mcap.parent / "report" / "b.png"
    assert s.report_file("report", "notes.txt") is None and s.report_file("static", "b.png") is None
    s.on_diagnostics([status("mcap_recorder: recorder", "idle", 0, path="", last_file=str(mcap))], now=2.0)
    assert s.recorder.view() == {"path": str(mcap), "state": "finished"}
    s.on_diagnostics([status("mcap_recorder: recorder", "idle", 0, path="", last_file="")], now=3.0)
    assert s.recorder.view()["state"] == "finished"  # nothing named: the last file stays


def test_a_recorder_status_with_a_bad_path_is_refused(tmp_path):
    s = suite()
    refused = s.on_diagnostics([status("mcap_recorder: recorder", "recording", 0, path="a\x07b")], now=1.0)
    assert len(refused) == 1 and s.recorder.path is None
    assert "mcap_recorder: recorder" in s.nodes  # the status itself is shown


def test_the_report_is_listed_again_and_a_missing_folder_is_no_report(tmp_path):
    assert report_files(None) == [] and report_files(str(tmp_path / "gone" / "run.mcap")) == []
    s = suite()
    mcap = tmp_path / "run2" / "run.mcap"
    mcap.parent.mkdir()
    s.on_diagnostics([status("mcap_recorder: recorder", "recording", 0, path=str(mcap))], now=1.0)
    assert s.report == []
    write_report(tmp_path / "run2")  # the report is written after the run
    s.list_report()
    assert s.report == ["a.md", "b.png", "c.json"]
