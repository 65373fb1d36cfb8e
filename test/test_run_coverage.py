"""What a run's recording covers (analysis.run_coverage: stream_gaps, recording_coverage, restart_gaps,
recording_problems) and reading a run folder of several files as one recording (mcap_log RunFiles): a
recorder that restarted leaves two files and a gap, and the summary says so instead of "100 %"."""

from __future__ import annotations

import numpy as np
import pytest

from stewart_vibration.analysis.run_coverage import recording_coverage, recording_problems, restart_gaps, stream_gaps
from stewart_vibration.analysis.run_signals import load_signals
from stewart_vibration.mcap_log import McapRunWriter
from stewart_vibration.mcap_log.reader import RunFiles, open_run
from stewart_vibration.messages.stream_health import SequenceGaps

PERIOD_NS = 2_000_000


def stamps(lo_s, hi_s):
    return np.arange(round(lo_s * 1e9), round(hi_s * 1e9) + 1, PERIOD_NS, dtype=np.int64)


def test_a_stream_without_gaps_covers_its_span():
    out = stream_gaps(stamps(10.0, 12.0))
    assert out["period_s"] == pytest.approx(0.002) and out["gaps"] == [] and out["missing"] == 0
    assert out["recorded"] == out["expected"] == 1001


def test_gaps_inside_and_at_the_ends_of_the_span_are_counted():
    t = np.concatenate([stamps(10.0, 12.0), stamps(12.6, 20.0)])  # 0.6 s missing, as after a respawn
    out = stream_gaps(t, 9.0, 21.0)
    assert [(round(g["start_s"], 3), round(g["end_s"], 3), g["missing"]) for g in out["gaps"]] == [
        (9.0, 10.0, 500), (12.0, 12.6, 299), (20.0, 21.0, 500)]  # 9.000..9.998, 12.002..12.598, 20.002..21.000
    assert out["expected"] == 6001 and out["recorded"] == len(t) == 6001 - 500 - 299 - 500
    assert out["missing"] == 500 + 299 + 500


def test_one_lost_sample_is_a_gap():
    t = np.delete(stamps(0.0, 1.0), 100)
    (gap,) = stream_gaps(t)["gaps"]
    assert gap["missing"] == 1 and gap["end_s"] - gap["start_s"] == pytest.approx(0.004)


def write_part(path, lo_s, hi_s, topic="/s/legs/joint_states"):
    """A file of JointStates stamped every 2 ms from lo_s to hi_s (real CDR), as one recorder start writes."""
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    T = store.types
    w = McapRunWriter(path)
    w.add_topic(topic, "sensor_msgs/msg/JointState", "[]")
    for ns in stamps(lo_s, hi_s):
        h = T["std_msgs/msg/Header"](T["builtin_interfaces/msg/Time"](int(ns // 10**9), int(ns % 10**9)), "")
        msg = T["sensor_msgs/msg/JointState"](h, ["leg_1"], np.zeros(1), np.zeros(1), np.zeros(1))
        w.submit(topic, int(ns), bytes(store.serialize_cdr(msg, "sensor_msgs/msg/JointState")))
    w.close()


def test_a_run_folder_of_two_files_is_read_whole_and_its_gap_reported(tmp_path):
    # the second file's name sorts first: the order comes from the files' times, not their names
    write_part(tmp_path / "run_b.mcap", 1.0, 3.0)
    write_part(tmp_path / "run_a.mcap", 3.6, 5.0)
    run = open_run(tmp_path)
    assert isinstance(run, RunFiles) and [r.path.name for r in run.files] == ["run_b.mcap", "run_a.mcap"]
    assert run.message_count() == 1001 + 701
    signals = load_signals(tmp_path)
    assert signals["joints"][0].size == 0  # one name only: not a full joint state, but every stamp is counted
    cov = recording_coverage(signals, (1.0 - 0.5, 5.0 + 0.1))  # the runner's span, with its margins
    assert [f["file"] for f in cov["files"]] == ["run_b.mcap", "run_a.mcap"]
    assert [f["states"] for f in cov["files"]] == [1001, 701]
    assert cov["recorded"] == 1702 and cov["expected"] == 2001 and cov["ratio"] == pytest.approx(1702 / 2001)
    (gap,) = cov["gaps"]
    assert gap["start_s"] == pytest.approx(3.0) and gap["end_s"] == pytest.approx(3.6) and gap["missing"] == 299
    restarts = restart_gaps(signals, [{"node": "mcap_recorder", "exit_code": -9, "sim_time_s": 3.2},
                                      {"node": "vibration_planner", "exit_code": -9, "sim_time_s": 4.0}])
    assert restarts[0]["gap_s"] == pytest.approx((3.0, 3.6)) and restarts[1]["stream"] is None
    problems = recording_problems(cov, restarts)
    assert problems[0] == "the recording has a gap from 3.000 s to 3.600 s (0.600 s, 299 states not recorded)"
    assert "mcap_recorder exited with code -9 at 3.200 s and was restarted; its legs/joint_states stopped at " \
           "3.000 s and resumed at 3.600 s (0.600 s gap)" in problems
    assert any("vibration_planner" in p and "no 500 Hz output" in p for p in problems)


def test_a_recovered_file_replaces_its_cut_original(tmp_path):
    write_part(tmp_path / "run_1.mcap", 1.0, 2.0)
    data = (tmp_path / "run_1.mcap").read_bytes()
    (tmp_path / "run_1.mcap").write_bytes(data[: len(data) // 2])  # cut
    write_part(tmp_path / "run_1.recovered.mcap", 1.0, 2.0)
    run = open_run(tmp_path)
    assert run.path.name == "run_1.recovered.mcap"


def test_a_cut_file_in_the_folder_is_read_and_named(tmp_path):
    write_part(tmp_path / "run_1.mcap", 1.0, 2.0)
    write_part(tmp_path / "run_2.mcap", 2.5, 3.0)
    data = (tmp_path / "run_1.mcap").read_bytes()
    (tmp_path / "run_1.mcap").write_bytes(data[:-200])  # the summary is gone: cut, every chunk whole
    signals = load_signals(tmp_path)
    cov = recording_coverage(signals)
    assert [f["complete"] for f in cov["files"]] == [False, True] and cov["recorded"] == 501 + 251
    assert any("run_1.mcap was cut short" in p for p in recording_problems(cov, []))


def test_sequence_gaps_count_missing_numbers_per_publisher():
    gaps = SequenceGaps()
    for n in (1, 2, 3, 7, 8, 1, 2, 5):  # 4..6 missing; a new publisher starts at 1; then 3..4 missing
        gaps.seen("/clock", n)
    gaps.seen("/clock", None)
    assert gaps.total == 5 and gaps.per_topic() == {"/clock": 5}



def test_guard_trips_leave_out_statuses_that_cannot_be_read_and_keep_the_rest_in_time_order():
    """A spoofed guard status in a recording (a trip time NaN, a state or limit outside the table) is left out of
    the trips; the readable trips come in order of their trip time, each with its last values."""
    from malformed_messages import good_guard_status
    from rclpy.serialization import serialize_message

    from stewart_vibration.analysis.tissue_figures import guard_trips
    from stewart_vibration_interfaces.msg import ForceGuardStatus

    def status(time_s=2.0, peak=1.0, **fields):
        msg = good_guard_status()
        msg.trip_time_s, msg.peak_force_n = time_s, peak
        for name, value in fields.items():
            setattr(msg, name, value)
        return serialize_message(msg)

    statuses = [status(12.5), status(state=ForceGuardStatus.ARMED), status(float("nan")), status(3.25),
                status(4.0, trip_limit=9), status(state=7), status(12.5, peak=2.0), b"\x00\x01\x00\x00garbage"]
    trips = guard_trips({"guard_status": statuses})
    assert [t.trip_time_s for t in trips] == [3.25, 12.5]
    assert trips[1].peak_force_n == 2.0


def test_statuses_of_a_log_from_before_the_typed_statuses_are_left_out_and_counted(tmp_path):
    """A run folder with vibration/status recorded as diagnostic_msgs/DiagnosticStatus (a log from before the
    typed statuses) and as VibrationUnitsStatus: the typed ones are read, the old ones counted as untyped, not
    as malformed (they are no spoof)."""
    from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
    from malformed_messages import good_vibration_status
    from rclpy.serialization import serialize_message

    from stewart_vibration.analysis.run_coverage import stream_summary

    write_part(tmp_path / "run_a.mcap", 1.0, 1.2)
    old = McapRunWriter(tmp_path / "run_b.mcap")
    old.add_topic("/s/vibration/status", "diagnostic_msgs/msg/DiagnosticStatus", "[]")
    old_status = DiagnosticStatus(name="hardware_emulator: vibration", message="idle",
                                  values=[KeyValue(key="state", value="idle")])
    old.submit("/s/vibration/status", 1_300_000_000, serialize_message(old_status))
    old.close()
    new = McapRunWriter(tmp_path / "run_c.mcap")
    new.add_topic("/s/vibration/status", "stewart_vibration_interfaces/msg/VibrationUnitsStatus", "[]")
    new.submit("/s/vibration/status", 1_400_000_000, serialize_message(good_vibration_status()))
    new.close()
    signals = load_signals(tmp_path)
    assert len(signals["vibration_status"]) == 1 and signals["untyped_statuses"] == {"vibration/status": 1}
    streams = stream_summary(signals)
    assert streams["malformed_statuses"] == [] and streams["untyped_statuses"] == {"vibration/status": 1}
    assert streams["windows"]["accepted"] == 3  # the typed status's count
