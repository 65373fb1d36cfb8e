"""The recorder's faults from the user's side, over real DDS: hostile output_dir / file_pattern refused with
the reason and no file written outside the run folder; a full disk (a small tmpfs) reported at once as
ERROR with the file kept readable; a recorder stopped (SIGSTOP) whose lost samples are counted from DDS's
own events and sequence numbers; a bag of two files (stop, start) summarised whole with its gap.

Waits are on what can be observed (log lines, /diagnostics, files on disk), never fixed sleeps."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import pytest
from small_filesystem import small_filesystem

from stewart_vibration.mcap_log import RunReader
from stewart_vibration.mcap_log.files import read_layout
from stewart_vibration.runtime.processes import start_python_module, wait_for

pytestmark = pytest.mark.integration

RECORDER = "stewart_vibration.nodes.mcap_recorder_node"
PUBLISHER = "synthetic_run_publisher"
JS, CLOCK = "/legs/joint_states", "/clock"


def _env(ros_domain, **extra):
    from stewart_vibration.runtime.processes import ros_environment

    env = ros_environment(ros_domain)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(Path(__file__).parent), env.get("PYTHONPATH")]))
    env.update(extra)
    return env


def _stats(proc) -> dict:
    lines = [x for x in proc.log_text().splitlines() if x.startswith("MCAP_RECORDER_STATS ")]
    assert lines, proc.log_text()
    return json.loads(lines[-1].split(" ", 1)[1])


def _sent(pub) -> dict:
    line = next(x for x in pub.log_text().splitlines() if x.startswith("SYNTHETIC_SENT "))
    return json.loads(line.split(" ", 1)[1])["counts"]


def _tree(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*") if p.is_file()}


def _refused(cwd: Path, env, *params: str) -> str:
    """Start a recorder in ``cwd`` with ``params``; assert it refuses in one line (exit 2); return the line."""
    args = [a for p in params for a in ("-p", p)]
    out = subprocess.run([sys.executable, "-m", RECORDER, "--ros-args", *args], cwd=cwd, env=env,
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 2, out.stdout + out.stderr
    assert "Traceback" not in out.stderr, out.stderr
    (line,) = [x for x in out.stderr.splitlines() if x.strip()]
    assert line.startswith("[FATAL] cannot start: InvalidInputError:"), line
    return line


def test_hostile_paths_and_patterns_are_refused_and_write_nothing_outside(ros_domain, tmp_path):
    env = _env(ros_domain)
    work = tmp_path / "work"
    work.mkdir()
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    foreign = tmp_path / "foreign_bag"
    foreign.mkdir()
    (foreign / "metadata.yaml").write_text("rosbag2_bagfile_information:\n  version: 9\n  custom_data: ~\n")
    foreign_meta = (foreign / "metadata.yaml").read_bytes()
    before = _tree(tmp_path)
    cases = [
        # quoted: a ROS argument's value is YAML, and {...} alone would be a YAML mapping
        (["file_pattern:='{node.__class__.__mro__}.mcap'"], "unknown placeholder {node.__class__.__mro__}"),
        (["file_pattern:='{0}.mcap'"], "unknown placeholder {0}"),
        (["file_pattern:='../escape_{stamp}.mcap'"], "no path separator"),
        ([f"file_pattern:={tmp_path}/abs.mcap"], "no path separator"),
        (["file_pattern:=run.txt"], "must end in '.mcap'"),
        (["output_dir:=../outside"], "'..' is not allowed"),
        ([f"output_dir:={blocker}"], "is a file"),
        ([f"output_dir:={tmp_path}/missing/deeper"], "does not exist"),
        ([f"output_dir:={foreign}"], "did not write"),
    ]
    for params, words in cases:
        assert words in _refused(work, env, *params), params
    assert _tree(tmp_path) == before  # nothing written anywhere, the foreign bag untouched
    assert (foreign / "metadata.yaml").read_bytes() == foreign_meta


def test_refused_at_run_time_and_a_standalone_recorder_makes_its_own_run_folder(ros_domain, tmp_path):
    from rcl_interfaces.msg import Parameter as ParameterMsg
    from rcl_interfaces.msg import ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters
    from ros_client import RosTestClient

    from stewart_vibration_interfaces.msg import Outcome

    env = _env(ros_domain)
    work = tmp_path / "work"
    (work / "runs").mkdir(parents=True)
    (work / "runs" / "older").mkdir()  # a runs root with other things in it
    log = open(tmp_path / "recorder.log", "w")  # noqa: SIM115 - closed below
    rec = subprocess.Popen([sys.executable, "-m", RECORDER, "--ros-args", "-p", "topics:=[/legs/joint_states]"],
                           cwd=work, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    client = RosTestClient()
    try:
        assert wait_for(lambda: "recording to" in (tmp_path / "recorder.log").read_text(), 30)
        folders = [p for p in (work / "runs").iterdir() if p.name.startswith("run_")]
        assert len(folders) == 1 and (work / "runs" / "latest").resolve() == folders[0].resolve()

        def set_param(name, value):
            msg = ParameterMsg(name=name, value=ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=value))
            return client.call(SetParameters, "/mcap_recorder/set_parameters",
                               SetParameters.Request(parameters=[msg])).results[0]

        for name, value, words in (("file_pattern", "{0}.mcap", "unknown placeholder {0}"),
                                   ("file_pattern", "../x.mcap", "no path separator"),
                                   ("output_dir", "../../x", "'..' is not allowed"),
                                   ("output_dir", "runs", "is a runs folder")):
            result = set_param(name, value)
            assert not result.successful and words in result.reason, (name, value, result.reason)
        assert set_param("file_pattern", "part_{index}_{node}.mcap").successful
        assert client.stop_recording().outcome.code == Outcome.SUCCEEDED
        started = client.start_recording()
        assert started.outcome.code == Outcome.SUCCEEDED
        assert started.path == str(folders[0].resolve() / "part_2_mcap_recorder.mcap")
        assert client.stop_recording().outcome.code == Outcome.SUCCEEDED
        # typed refusals: nothing to stop; a second start while recording; a name that is not a plain file name
        assert client.stop_recording().outcome.code == \
            Outcome.NOT_RECORDING
        named = client.start_recording("reduction_1")
        assert named.outcome.code == Outcome.SUCCEEDED and named.path.endswith("/reduction_1.mcap"), named
        again = client.start_recording("other")
        assert again.outcome.code == Outcome.BUSY and again.path == named.path
        assert client.stop_recording().outcome.code == Outcome.SUCCEEDED
        bad = client.start_recording("../escape")
        assert bad.outcome.code == Outcome.INVALID_ARGUMENT and "separator" in bad.outcome.message, bad
    finally:
        client.close()
        os.killpg(rec.pid, signal.SIGINT)
        rec.wait(20)
        log.close()
    assert not (work / "runs" / "metadata.yaml").exists()  # runs/ is not turned into one bag
    assert (folders[0] / "metadata.yaml").is_file()
    outside = {p for p in _tree(tmp_path) if not p.startswith(str(folders[0].relative_to(tmp_path)))}
    assert outside == {"recorder.log"}, outside


def test_a_full_disk_is_an_error_at_once_and_the_file_stays_readable(ros_domain, tmp_path):
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
    from ros_client import RosTestClient

    from stewart_vibration_interfaces.msg import Outcome

    env = _env(ros_domain)
    with small_filesystem(tmp_path / "small", 512 * 1024) as fs:
        rec = start_python_module("recorder", RECORDER, ["--ros-args", "-p", f"output_dir:={fs}",
                                                         "-p", "flush_period_s:=0.2"], env, tmp_path / "logs")
        client = RosTestClient()
        statuses = []  # (monotonic time, DiagnosticStatus) of the recorder
        client.node.create_subscription(DiagnosticArray, "/diagnostics", lambda m: statuses.extend(
            (time.monotonic(), s) for s in m.status if s.name.startswith("mcap_recorder")), 100)
        pub = None
        try:
            assert wait_for(lambda: "recording to" in rec.log_text(), 30), rec.log_text()
            (path,) = list(fs.glob("*.mcap"))
            pub = start_python_module("publisher", PUBLISHER, ["--count", "10000", "--rate", "500"], env,
                                      tmp_path / "logs")
            grew = [time.monotonic(), 0]  # when the file last grew, its size

            def failed():
                size = path.stat().st_size
                if size != grew[1]:
                    grew[:] = [time.monotonic(), size]
                return any({kv.key: kv.value for kv in s.values}.get("fault") == "write_failed" for _t, s in statuses)

            assert client.spin_until(failed, 60), rec.log_text()
            first_error = next(t for t, s in statuses if s.level == DiagnosticStatus.ERROR)
            assert pub.alive()  # reported while the run goes on, not at the end
            delay = first_error - grew[0]
            print(f"full disk: ERROR on /diagnostics {delay:.2f} s after the file last grew "
                  f"({grew[1]:,} bytes)")
            assert delay < 2.0
            error = next(s for _t, s in statuses if s.level == DiagnosticStatus.ERROR)
            values = {kv.key: kv.value for kv in error.values}
            assert values["fault_code"] == "ENOSPC" and "No space left on device" in values["fault_reason"]
            assert error.message.startswith("recording failed:")
            client.spin_for(1.5)  # the 1 s report: never OK again
            later = [s for t, s in statuses if t > first_error]
            assert later and all(s.level == DiagnosticStatus.ERROR for s in later)
            answer = client.stop_recording()
            assert answer.outcome.code == Outcome.RECORDING_FAILED and "ENOSPC" in answer.outcome.message
        finally:
            client.close()
            if pub is not None:
                pub.stop()
            rec.stop()
        stats = _stats(rec)
        assert stats["failure"]["code"] == "ENOSPC" and stats["failure"]["lost_after_failure"] > 0
        layout = read_layout(path)
        assert layout.partial is None and layout.bytes_unread == 0 and layout.chunks > 0  # whole chunks only
        run = RunReader(path)
        counts = Counter(m.topic for m in run.messages())
        assert counts[JS] > 100
        assert not (fs / "metadata.yaml").exists() or path.name not in (fs / "metadata.yaml").read_text()
        assert "mcap-recover" in rec.log_text()


def test_a_recorder_on_sim_time_records_what_it_discovers_while_clock_is_silent(ros_domain, tmp_path):
    """A recorder on sim time beside publishers but no /clock (as one respawned while /clock is not yet matched)
    still discovers and records their topics: discovery does not wait for sim time to move."""
    env = _env(ros_domain)
    folder = tmp_path / "bag"
    rec = start_python_module("recorder", RECORDER, ["--ros-args", "-p", "use_sim_time:=true", "-p",
                                                     f"output_dir:={folder}"], env, tmp_path / "logs")
    pub = None
    try:
        assert wait_for(lambda: "recording to" in rec.log_text(), 30), rec.log_text()
        pub = start_python_module("publisher", PUBLISHER, ["--count", "1000", "--rate", "100", "--topics",
                                                           "joint_states"], env, tmp_path / "logs")
        assert wait_for(lambda: f"subscribed {JS}" in rec.log_text(), 30), rec.log_text()
        (path,) = list(folder.glob("*.mcap"))

        def recorded() -> int:
            try:
                return sum(1 for _ in RunReader(path).messages([JS]))
            except Exception:  # noqa: BLE001 - being written
                return 0

        assert wait_for(lambda: recorded() > 100, 30), rec.log_text()[-3000:]
    finally:
        if pub is not None:
            pub.stop()
        rec.stop()


@pytest.mark.parametrize("executor", ["events", "single"])
def test_a_stopped_recorder_counts_what_it_lost(ros_domain, tmp_path, executor):
    """SIGSTOP for 2 s while a 500 Hz /clock (publisher history 0.2 s) and joint states flow: the samples DDS
    could not deliver are found in the recording (the gaps in /clock's values), and with the single-threaded
    executor the recorder counts them itself from the publication sequence numbers: recorded + lost is what
    was sent, topic by topic."""
    env = _env(ros_domain, **({"STEWART_EXECUTOR": "single"} if executor == "single" else {}))
    folder = tmp_path / "bag"
    rec = start_python_module("recorder", RECORDER, ["--ros-args", "-p", f"output_dir:={folder}",
                                                     "-p", f"topics:=[{JS},{CLOCK}]"], env, tmp_path / "logs")
    pub = None
    try:
        assert wait_for(lambda: "recording to" in rec.log_text(), 30), rec.log_text()
        pub = start_python_module("publisher", PUBLISHER, ["--count", "6000", "--rate", "500", "--topics",
                                                           "joint_states,clock"], env, tmp_path / "logs")
        assert wait_for(lambda: "subscribed /clock" in rec.log_text() and "subscribed /legs/joint_states"
                        in rec.log_text(), 30), rec.log_text()
        (path,) = list(folder.glob("*.mcap"))

        def recorded(topic):
            try:
                return sum(1 for _ in RunReader(path).messages([topic]))
            except Exception:  # noqa: BLE001 - being written
                return 0

        # 2 s of flow first: the link is settled (discovery over) before the recorder is frozen, so what is
        # measured is the loss of samples, not a link still being set up while its reader cannot answer
        assert wait_for(lambda: recorded(CLOCK) >= 1000, 30)
        os.killpg(rec.popen.pid, signal.SIGSTOP)
        stopped = time.monotonic()
        while time.monotonic() - stopped < 2.0:
            time.sleep(0.05)
        os.killpg(rec.popen.pid, signal.SIGCONT)
        before = recorded(CLOCK)
        assert pub.alive(), "the publisher ended before the recorder was stopped for 2 s (12 s of samples)"
        assert wait_for(lambda: recorded(CLOCK) > before + 100, 20), \
            f"the recorder records nothing after it was resumed ({before} /clock samples):\n{rec.log_text()[-3000:]}"
        assert wait_for(lambda: not pub.alive(), 60), pub.log_text()
        sent = _sent(pub)
        assert wait_for(lambda: recorded(JS) + recorded(CLOCK) > 0, 10)
        os.killpg(rec.popen.pid, signal.SIGINT)
        assert wait_for(lambda: not rec.alive(), 20), rec.log_text()
    finally:
        if pub is not None:
            pub.stop()
        rec.stop()
    from stewart_vibration.analysis.run_coverage import recording_coverage
    from stewart_vibration.analysis.run_signals import load_signals

    stats = _stats(rec)
    counts = Counter(m.topic for m in RunReader(path).messages())
    clock = recording_coverage(load_signals(folder))["clock"]
    print(f"{executor}: sent {sent}, recorded {dict(counts)}, /clock ticks missing in the recording "
          f"{clock['missing']} ({clock['gap_count']} gaps), recorder's sequence gaps {stats['sequence_gaps']}")
    states = recording_coverage(load_signals(folder))  # the joint states' own gaps (2 s of publisher history)
    assert clock["missing"] > 0 and counts[CLOCK] + clock["missing"] == sent[CLOCK]  # found in the recording
    assert counts[JS] + states["missing"] == sent[JS]
    if executor == "single":
        expected = {t: sent[t] - counts[t] for t in (JS, CLOCK) if sent[t] > counts[t]}
        assert stats["sequence_gaps"] == expected and stats["lost"] == clock["missing"] + states["missing"]
    else:
        assert stats["sequence_gaps"] is None


def test_a_bag_of_two_recordings_is_summarised_whole_with_its_gap(ros_domain, tmp_path):
    from ros_client import RosTestClient

    from stewart_vibration.analysis.run_coverage import recording_coverage, recording_problems
    from stewart_vibration.analysis.run_signals import load_signals
    from stewart_vibration_interfaces.msg import Outcome

    env = _env(ros_domain)
    folder = tmp_path / "bag"
    rec = start_python_module("recorder", RECORDER, ["--ros-args", "-p", f"output_dir:={folder}",
                                                     "-p", "file_pattern:=part_{index}.mcap"], env, tmp_path / "logs")
    client = RosTestClient()
    try:
        assert wait_for(lambda: "recording to" in rec.log_text(), 30), rec.log_text()
        for part, start_s in ((1, 1000.0), (2, 1003.0)):  # 2 s each, the second from 3 s on: a 1 s gap
            if part == 2:
                assert client.start_recording().outcome.code == Outcome.SUCCEEDED
            pub = start_python_module(f"publisher{part}", PUBLISHER, ["--count", "1000", "--rate", "500",
                                                                       "--start-s", str(start_s)],
                                      env, tmp_path / "logs")
            assert wait_for(lambda p=pub: not p.alive(), 60), pub.log_text()
            pub.stop()
            sent = _sent(pub)[JS]

            def on_disk(p=part, n=sent):
                try:
                    return sum(1 for _ in RunReader(folder / f"part_{p}.mcap").messages([JS])) >= n
                except Exception:  # noqa: BLE001 - being written
                    return False

            assert client.spin_until(on_disk, 30)
            assert client.stop_recording().outcome.code == Outcome.SUCCEEDED
    finally:
        client.close()
        rec.stop()
    cov = recording_coverage(load_signals(folder))
    assert [f["file"] for f in cov["files"]] == ["part_1.mcap", "part_2.mcap"]
    assert [f["states"] for f in cov["files"]] == [1000, 1000]
    (gap,) = cov["gaps"]
    assert abs(gap["start_s"] - 1001.998) < 1e-6 and abs(gap["end_s"] - 1003.0) < 1e-6
    assert cov["recorded"] == 2000 and cov["expected"] == 2500 and cov["ratio"] == 0.8
    assert recording_problems(cov, [])[0].startswith("the recording has a gap from 1001.998 s to 1003.000 s")
    out = subprocess.run([sys.executable, "-m", "stewart_vibration", "report", str(folder), "--out",
                          str(tmp_path / "report")], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    summary = json.loads((tmp_path / "report" / "summary.json").read_text())
    assert [Path(f).name for f in summary["files"]] == ["part_1.mcap", "part_2.mcap"]
    assert summary["topics"][JS]["count"] == 2000
