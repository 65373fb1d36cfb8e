"""The recorder's bag folders and its reports, without ROS: where files go and what they are called, the
metadata.yaml they are listed in (read back with rosbags, an independent rosbag2 reader), an earlier recorder's
files taken over, a failed file left out; the recording's /diagnostics status and its finished report."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from rosbags.rosbag2 import Reader
from test_mcap_bag_directory import _write_ours

from stewart_vibration.errors import InvalidInputError
from stewart_vibration.mcap_log.bag_folders import BagFolders
from stewart_vibration.mcap_log.reader import bag_file_of
from stewart_vibration.mcap_log.recording_status import ERROR, OK, WARN, finished_report, recording_status
from stewart_vibration.mcap_log.writer import WriteFailure, WriterStats
from stewart_vibration.messages.stream_health import SequenceGaps


def test_output_dir_empty_makes_one_run_folder_and_a_new_one_once_it_is_gone(tmp_path):
    made = []

    def new_run_folder() -> Path:
        made.append(tmp_path / "runs" / f"run_{len(made)}")
        made[-1].mkdir(parents=True)
        return made[-1]

    bags = BagFolders(tmp_path, new_run_folder)
    first = bags.folder("")
    assert bags.folder("") == first == tmp_path / "runs" / "run_0"
    first.rmdir()
    assert bags.folder("") == tmp_path / "runs" / "run_1"
    assert bags.folder("bag") == tmp_path / "bag" and (tmp_path / "bag").is_dir()
    with pytest.raises(InvalidInputError):
        bags.folder("../outside")


def test_names_count_the_files_of_the_folder_and_never_overwrite(tmp_path):
    bags = BagFolders(tmp_path, lambda: tmp_path)
    folder = bags.folder("bag")
    assert bags.next_path(folder, "part_{index}.mcap", "rec") == folder / "part_1.mcap"
    (folder / "part_1.mcap").write_bytes(b"")
    assert bags.next_path(folder, "part_{index}.mcap", "rec") == folder / "part_1_1.mcap"
    assert bags.next_path(folder, "{node}.mcap", "rec") == folder / "rec.mcap"
    with pytest.raises(InvalidInputError):
        bags.next_path(folder, "../x.mcap", "rec")


def test_an_earlier_recorders_files_stay_listed_and_a_failed_file_is_left_out(tmp_path):
    folder = tmp_path / "bag"
    folder.mkdir()
    _write_ours(folder, marked=True)  # run.mcap, listed by an earlier recorder
    bags = BagFolders(tmp_path, lambda: folder)
    assert bags.take_over(folder) == 1
    assert not (folder / "metadata.yaml").exists()  # none while a file is written
    assert bags.take_over(folder) is None  # adopted once
    other = tmp_path / "other"
    other.mkdir()
    _write_ours(other)
    (other / "run.mcap").rename(folder / "second.mcap")  # this recorder's new file
    metadata, listed = bags.finish(folder, bag_file_of(folder / "second.mcap"))
    assert listed == 2 and metadata == folder / "metadata.yaml"
    info = yaml.safe_load(metadata.read_text())["rosbag2_bagfile_information"]
    names = sorted(Path(p).name for p in info["relative_file_paths"])
    assert names == ["run.mcap", "second.mcap"]
    with Reader(folder) as reader:
        assert reader.message_count == 2 * (200 + 50)
    assert bags.finish(folder, None)[1] == 2  # a file whose write failed is not listed


def test_a_foreign_metadata_yaml_is_not_taken_over(tmp_path):
    folder = tmp_path / "bag"
    folder.mkdir()
    _write_ours(folder, marked=False)
    bags = BagFolders(tmp_path, lambda: folder)
    assert bags.take_over(folder) is None


def test_the_status_says_recording_dropped_lost_or_failed():
    gaps = SequenceGaps()
    for n in (1, 2, 5):
        gaps.seen("/a", n)
    stats = WriterStats(received=10, written=9, dropped=1)
    severity, message, values = recording_status(Path("/r/x.mcap"), stats, None, gaps)
    assert severity == WARN and "1 messages dropped" in message and "2 samples lost" in message
    assert values["lost"] == 2 and values["lost_topics"] == "/a:2" and values["sequence_gaps"] == 2
    assert recording_status(Path("/r/x.mcap"), WriterStats(received=3, written=3), None, None)[0] == OK
    severity, message, values = recording_status(None, None, ("ENOSPC", "disk full"), None)
    assert (severity, message, values["fault_code"], values["path"]) == (ERROR, "recording failed: disk full",
                                                                        "ENOSPC", "")
    assert recording_status(None, None, None, None)[:2] == (OK, "not recording")


def test_the_finished_report_carries_the_failure_and_the_losses():
    stats = WriterStats(received=5, written=4, lost_after_failure=1, per_topic={"/a": 4})
    report = finished_report(Path("/r/x.mcap"), stats, WriteFailure("EIO", "i/o error", 1024), None, 12.5, None)
    assert report["failure"] == {"code": "EIO", "reason": "i/o error", "good_bytes": 1024, "lost_after_failure": 1}
    assert (report["path"], report["stopped_at_s"], report["metadata_yaml"], report["lost"]) == \
        ("/r/x.mcap", 12.5, None, 0)
    assert report["sequence_gaps"] is None and report["per_topic"] == {"/a": 4}
