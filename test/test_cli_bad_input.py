"""Bad input to the CLI and the replay node, as a user would give it (issue 13): one clear line
naming the file and what is wrong, a non-zero exit, no traceback; bad numbers refused (exit 2);
``ik`` at a singular pose is the library's SingularPoseError."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from test_mcap_report import _write_run

from stewart_vibration import condition_number, inverse_kinematics
from stewart_vibration.runtime.processes import ros_environment

REPLAY = "stewart_vibration.nodes.mcap_replay_node"


def run_cli(*args, timeout=120):
    return subprocess.run([sys.executable, "-m", "stewart_vibration", *args], capture_output=True, text=True,
                          timeout=timeout)


def one_error_line(out) -> str:
    assert "Traceback" not in out.stderr, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr
    return lines[0]


@pytest.fixture(scope="module")
def bad_files(tmp_path_factory):
    """name -> path: a good run, its truncated copy, an empty file, random bytes, text, a folder without MCAP."""
    d = tmp_path_factory.mktemp("bad")
    good = d / "good" / "run.mcap"
    good.parent.mkdir()
    _write_run(good, n=300)
    data = good.read_bytes()
    files = {"good": good, "missing": d / "missing.mcap", "empty": d / "empty.mcap", "random": d / "random.mcap",
             "text": d / "notes.txt", "truncated": d / "truncated.mcap", "folder": d / "no_mcap_here"}
    files["empty"].write_bytes(b"")
    files["random"].write_bytes(np.random.default_rng(3).bytes(4096))
    files["text"].write_text("not a recording\n")
    files["truncated"].write_bytes(data[: len(data) // 2])
    files["folder"].mkdir()
    return files


EXPECTED = {
    "missing": "no such file",
    "empty": "empty file (0 bytes)",
    "random": "not an MCAP file",
    "text": "not an MCAP file",
    "truncated": "truncated MCAP",
    "folder": "neither metadata.yaml nor a .mcap file",
}


@pytest.mark.parametrize("kind", sorted(EXPECTED))
def test_report_refuses_bad_file_in_one_line(bad_files, tmp_path, kind):
    path = bad_files[kind]
    out = run_cli("report", str(path), "--out", str(tmp_path / "report"))
    assert out.returncode == 2
    line = one_error_line(out)
    assert str(path) in line and EXPECTED[kind] in line, line
    assert not (tmp_path / "report").exists()  # nothing half-written


def test_truncated_file_says_how_much_was_read(bad_files, tmp_path):
    path = bad_files["truncated"]
    line = one_error_line(run_cli("report", str(path), "--out", str(tmp_path / "r")))
    size = path.stat().st_size
    assert f"of {size:,} bytes read as whole records" in line and "complete chunks" in line
    assert f"mcap-recover {path}" in line
    # a user who wants what is there anyway
    out = run_cli("report", str(path), "--out", str(tmp_path / "r"), "--allow-truncated")
    assert out.returncode == 0, out.stderr
    assert "report:" in out.stdout


def test_report_accepts_the_run_folder(bad_files, tmp_path):
    from stewart_vibration.mcap_log.bag_metadata import BagFile, bag_metadata, write_metadata_yaml

    folder = bad_files["good"].parent
    write_metadata_yaml(folder, bag_metadata([BagFile("run.mcap")]))
    out = run_cli("report", str(folder), "--out", str(tmp_path / "r"))
    assert out.returncode == 0, out.stderr
    assert "report: 902 messages" in out.stdout


def test_report_output_path_error_is_one_line(bad_files, tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    out = run_cli("report", str(bad_files["good"]), "--out", str(blocker / "report"))
    assert out.returncode == 2
    assert str(blocker) in one_error_line(out)


def test_ik_at_singular_pose_is_a_typed_error(robot):
    pose = [0.0, 0.0, 0.16, 0.0, 0.0, 90.0]  # yaw 90 deg at home height: legs coplanar in pairs
    assert condition_number(robot, np.r_[pose[:5], np.radians(90.0)]) > 1e15
    for args in (["--deg"], ["--deg", "--json"]):
        out = run_cli("ik", *map(str, pose), *args)
        assert out.returncode == 2 and out.stdout == ""
        line = one_error_line(out)
        assert line.startswith("error: SingularPoseError:") and "condition number" in line


def test_ik_regular_pose_still_prints(robot):
    out = run_cli("ik", "0", "0", "0.16", "0", "0", "10", "--deg")
    assert out.returncode == 0 and "condition number" in out.stdout


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["fk", *["0.17"] * 6, "--tol", "-1"], "argument --tol: must be > 0, got -1"),
        (["fk", *["0.17"] * 6, "--tol", "0"], "argument --tol: must be > 0"),
        (["fk", *["0.17"] * 6, "--tol", "nan"], "argument --tol: 'nan' is not a finite number"),
        (["fk", *["0.17"] * 6, "--max-iter", "0"], "argument --max-iter: must be > 0"),
        (["fk", "0.17", "0.17", "0.17", "0.17", "0.17", "-0.17"], "argument L: must be > 0"),
        (["ik", "0", "0", "0.16", "0", "0", "inf"], "argument Q: 'inf' is not a finite number"),
        (["validate-dynamics", "--clinical-duration", "-1"], "argument --clinical-duration: must be > 0, got -1"),
        (["validate-dynamics", "--paper-duration", "0"], "argument --paper-duration: must be > 0"),
        (["validate-dynamics", "--timestep", "-0.001"], "argument --timestep: must be > 0"),
        (["validate-dynamics", "--clinical-duration", "1e-9"], "shorter than 10 simulation steps"),
    ],
)
def test_bad_numbers_refused(args, words):
    out = run_cli(*args)
    assert out.returncode == 2, out.stdout
    assert "Traceback" not in out.stderr and words in out.stderr, out.stderr


def test_fk_still_converges_with_a_valid_tolerance(robot):
    lengths = [str(v) for v in inverse_kinematics(robot, robot.home_pose)]
    out = run_cli("fk", *lengths, "--tol", "1e-10", "--json")
    assert out.returncode == 0, out.stderr


@pytest.mark.integration
@pytest.mark.parametrize("kind", sorted(EXPECTED))
def test_replay_node_refuses_bad_file_in_one_line(bad_files, ros_domain, kind):
    path = bad_files[kind]
    out = subprocess.run([sys.executable, "-m", REPLAY, "--ros-args", "-p", f"path:={path}"], capture_output=True,
                         text=True, timeout=60, env=ros_environment(ros_domain))
    assert out.returncode == 2, out.stdout + out.stderr
    line = one_error_line(out)
    assert line.startswith("mcap_replay: error:") and str(path) in line and EXPECTED[kind] in line, line
    if kind == "truncated":
        assert "bytes read as whole records" in line and "mcap-recover" in line


@pytest.mark.integration
def test_replay_node_refuses_bad_parameters(bad_files, ros_domain):
    for params, words in ((["rate:=-1"], "'rate' = -1 is outside"), (["clock_rate_hz:=nope"], "must be a number"),
                          ([], "parameter 'path'")):
        args = [a for p in ([f"path:={bad_files['good']}"] if params else []) + params for a in ("-p", p)]
        out = subprocess.run([sys.executable, "-m", REPLAY, "--ros-args", *args], capture_output=True, text=True,
                             timeout=60, env=ros_environment(ros_domain))
        assert out.returncode == 2, out.stdout + out.stderr
        assert words in one_error_line(out)
