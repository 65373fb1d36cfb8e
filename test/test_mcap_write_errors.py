"""The MCAP writer on a full disk and in a folder that disappears (mcap_log.writer): the failure is seen
at the write that fails, the file keeps every whole chunk before it (readable, recoverable), and nothing
submitted later is counted as written."""

from __future__ import annotations

import shutil
import struct
import time

import numpy as np
from small_filesystem import small_filesystem

from stewart_vibration.mcap_log import McapRunWriter, RunReader
from stewart_vibration.mcap_log.files import read_layout
from stewart_vibration.mcap_log.recover import recover

TOPIC = "/legs/joint_states"


def _fill(writer: McapRunWriter, limit_s: float = 20.0) -> int:
    """Submit numbered random payloads (incompressible, 4 KiB) until the writer reports a failure."""
    rng = np.random.default_rng(0)
    writer.add_topic(TOPIC, "sensor_msgs/msg/JointState", "[]")
    deadline, i = time.monotonic() + limit_s, 0
    while writer.failure is None and time.monotonic() < deadline:
        writer.submit(TOPIC, 10**9 + i * 2_000_000, struct.pack("<Q", i) + rng.bytes(4088))
        i += 1
        if i % 50 == 0:
            time.sleep(0.005)  # let the writer thread drain, as a 500 Hz stream would
    return i


def _numbers(path) -> list[int]:
    return [struct.unpack_from("<Q", m.data)[0] for m in RunReader(path).messages([TOPIC])]


def test_a_full_disk_stops_the_file_at_its_last_whole_chunk(tmp_path):
    with small_filesystem(tmp_path / "small", 1024 * 1024) as fs:
        path = fs / "run.mcap"
        writer = McapRunWriter(path, chunk_size=64 * 1024, flush_period_s=0.05)
        submitted = _fill(writer)
        failure = writer.failure
        assert failure is not None and failure.code == "ENOSPC", failure
        assert "No space left on device" in failure.reason and str(path) in failure.reason
        writer.submit(TOPIC, 0, b"late")  # after the failure: never written, counted
        stats = writer.close()  # no exception: the failure is reported, not raised
        assert stats.lost_after_failure >= 1
        layout = read_layout(path)
        assert layout.partial is None and layout.bytes_unread == 0  # cut back to whole records
        assert layout.good_end == failure.good_bytes == path.stat().st_size
        assert layout.chunks >= 5 and not layout.footer
        numbers = _numbers(path)
        assert numbers == list(range(len(numbers))) and 0 < len(numbers) < submitted  # a clean prefix
        report = recover(path, tmp_path / "rebuilt.mcap")  # the file is rebuilt without loss
        assert report.messages == len(numbers) and not report.corrupt_chunks and report.partial_chunk is None
        assert _numbers(tmp_path / "rebuilt.mcap") == numbers


def test_a_removed_folder_is_a_failure_not_a_silent_loss(tmp_path):
    folder = tmp_path / "bag"
    folder.mkdir()
    path = folder / "run.mcap"
    writer = McapRunWriter(path, chunk_size=1 << 20, flush_period_s=0.05)
    writer.add_topic(TOPIC, "sensor_msgs/msg/JointState", "[]")
    writer.submit(TOPIC, 1, b"x" * 100)
    shutil.rmtree(folder)
    deadline = time.monotonic() + 10
    while writer.failure is None and time.monotonic() < deadline:
        writer.submit(TOPIC, 2, b"y" * 100)
        time.sleep(0.01)
    assert writer.failure is not None and writer.failure.code == "ENOENT"
    assert "no longer names the file being written" in writer.failure.reason
    writer.close()
