"""The main job when its recording goes wrong, as a user runs it: a full disk (a small tmpfs) stops the
scenario safely and fails the verdict with the reason; a recorder killed and respawned under
--keep-running leaves two files, and the summary covers both and reports the gap and the restart."""

from __future__ import annotations

import json
import os
import signal
import time

import pytest
from small_filesystem import small_filesystem
from test_main_job import interrupt_for_summary, main_job, node_pids, processes_on_domain

pytestmark = [pytest.mark.integration, pytest.mark.slow]

# a vibration at home and nothing else: what these tests judge is the recording, not moves (which a busy
# machine slows down through the force guard)
VIBRATION_AT_HOME = """name: vibration_at_home
steps:
  - vibrate: {direction: [0.0, 0.0, 1.0], frame: platform, acceleration_g: 0.3, frequency_hz: 35.0,
              phase_rad: 0.0, duration_s: %s, ramp_s: 0.2}
"""


def scenario(tmp_path, duration_s: float):
    path = tmp_path / "vibration_at_home.yaml"
    path.write_text(VIBRATION_AT_HOME % duration_s)
    return str(path)


def _read_until(proc, lines, marker, deadline):
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        lines.append(line)
        if marker in line or not line:
            return any(marker in x for x in lines)
    return False


def fill(fs) -> int:
    """Fill the filesystem ``fs`` up to its last byte (as another program would); returns the bytes written."""
    import errno

    fd, written = os.open(fs / "filler", os.O_WRONLY | os.O_CREAT), 0
    try:
        while True:
            written += os.write(fd, b"\0" * (1 << 16))
    except OSError as exc:
        assert exc.errno == errno.ENOSPC
    finally:
        os.close(fd)
    return written


def test_a_full_disk_stops_the_scenario_safely_and_fails_the_run(tmp_path, ros_domain):
    """The disk fills up in the middle of the vibration: the recorder says so at once, the runner ramps the
    vibration out and waits for the robot to rest, the verdict fails with the reason (exit 2), and the summary
    of what was recorded is still written (its room was reserved at the start)."""
    with small_filesystem(tmp_path / "small", 64 * 1024 * 1024) as fs:
        out = fs / "run"
        proc = main_job(out, ros_domain, "--scenario", scenario(tmp_path, 60.0))
        lines: list[str] = []
        try:
            assert _read_until(proc, lines, "vibrating: started", time.monotonic() + 300), "".join(lines[-40:])
            print(f"filled the disk with {fill(fs):,} bytes during the vibration")
            rest, _ = proc.communicate(timeout=300)
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
        stdout = "".join(lines) + rest
        (tmp_path / "main_job.out").write_text(stdout)  # beside the small filesystem, for a failure's reader
        assert proc.returncode == 2, stdout[-4000:]
        assert "FAILED: the recorder stopped recording" in stdout and "ENOSPC" in stdout, stdout[-4000:]
        assert "stopping the scenario safely" in stdout and "the robot is at rest" in stdout, stdout[-4000:]
        assert "the vibration is cancelled: the units ramp out" in stdout  # ramped out, not run to its end
        assert "vibration done" not in stdout
        summary = json.loads((out / "summary.json").read_text())
        assert "ENOSPC" in summary["failure"]
        assert any(p.startswith("the recording failed:") for p in summary["problems"]), summary["problems"]
        rec = summary["recording"]
        assert rec["files"] and rec["recorded"] > 1000 and rec["gaps"]  # what was recorded, and the tail missing
        assert rec["gaps"][-1]["end_s"] == rec["span_s"][1]
        assert not [row["line"] for row in summary["limits"] if row["violations"]]
        assert not processes_on_domain(ros_domain)


def test_a_respawned_recorder_leaves_a_run_whose_summary_covers_both_files(tmp_path, ros_domain):
    out = tmp_path / "run"
    proc = main_job(out, ros_domain, "--scenario", scenario(tmp_path, 1.2), "--keep-running")
    lines: list[str] = []
    try:
        deadline = time.monotonic() + 300
        assert _read_until(proc, lines, "Nodes are running", deadline), "".join(lines[-40:])
        (recorder,) = node_pids(ros_domain, "nodes.mcap_recorder_node")
        os.kill(recorder, signal.SIGKILL)
        assert _read_until(proc, lines, "restarting it", deadline), "".join(lines[-20:])
        # the new recorder writes a second file into the same run folder; wait until it holds states
        from stewart_vibration.mcap_log import RunReader

        def second_file_has_states():
            files = sorted(out.glob("*.mcap"), key=os.path.getmtime)
            if len(files) < 2:
                return False
            try:
                return sum(1 for _ in RunReader(files[-1]).messages(["/stewart/legs/joint_states"])) > 1000
            except Exception:  # noqa: BLE001 - being written
                return False

        while time.monotonic() < deadline and not second_file_has_states():
            time.sleep(0.2)
        assert second_file_has_states()
    except BaseException:
        os.killpg(proc.pid, signal.SIGKILL)
        raise
    summary, rest = interrupt_for_summary(proc, lines, out)
    rec = summary["recording"]
    assert len(rec["files"]) == 2 and [f["complete"] for f in rec["files"]] == [False, True], rec["files"]
    assert sum(f["states"] for f in rec["files"]) >= rec["recorded"]  # the files also hold the start-up
    assert rec["gaps"] and rec["ratio"] < 1.0  # the respawn left a gap, and the coverage says so
    (restart,) = summary["restarts"]
    assert restart["node"] == "mcap_recorder" and restart["exit_code"] == -9
    start, end = restart["gap_s"]
    assert end is not None and 0 < end - start < 30
    assert any(g["start_s"] <= start + 1e-6 and g["end_s"] >= end - 1e-6 for g in rec["gaps"])
    assert any(p.startswith("mcap_recorder exited with code -9") for p in summary["problems"])
    assert "recording: 2 file(s)" in rest and "PROBLEM: the recording has a gap" in rest
    assert summary["vibrations"] and summary["vibrations"][0]["amplitude_error"] < 0.02  # from the first file
    assert not [row["line"] for row in summary["limits"] if row["violations"]]  # over both files
    assert not processes_on_domain(ros_domain)
