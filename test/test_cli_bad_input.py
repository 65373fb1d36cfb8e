"""Bad input to the CLI and the node executables, as a user would give it: one clear line on stderr
naming the file (or option) and what is wrong, a non-zero exit, no traceback, within 10 s. Every
subcommand x every input class: config files that are missing, a directory, a FIFO, /dev/zero, huge,
not UTF-8, a YAML bomb, too deep, recursive, not YAML, not a mapping, of wrong types; numbers that are
NaN, inf, negative, huge or not numbers; bad ROS names; bad MCAPs. Most run the CLI in-process (fast,
and a hang is caught by a thread timeout); a few run it as the user does, as a process."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml
from test_mcap_report import _write_run

from stewart_vibration import condition_number, inverse_kinematics
from stewart_vibration.cli.main import main
from stewart_vibration.runtime.processes import ros_environment

REPLAY = "stewart_vibration.nodes.mcap_replay_node"


CONFIG = Path(__file__).resolve().parents[1] / "stewart_vibration" / "config"
DEADLINE_S = 10.0  # every refusal, as the issue asks: a config or option never takes longer to refuse


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
    files.update(corrupted_copies(good, d))
    return files


def corrupted_copies(good, d) -> dict:
    """name -> path: copies of ``good`` each damaged in one way a reader must not trust (the MCAP spec's
    checks: chunk CRC and size, data section CRC, summary CRC, record structure)."""
    import struct

    from stewart_vibration.mcap_log.files import CHUNK, FOOTER, read_layout

    data = good.read_bytes()
    layout = read_layout(good)
    chunks = [(start, length) for opcode, start, length in layout.records if opcode == CHUNK]
    (data_end,) = [start for opcode, start, _ in layout.records if opcode == 0x0F]
    (footer,) = [start for opcode, start, _ in layout.records if opcode == FOOTER]
    first, first_len = chunks[0]
    name_len = struct.unpack_from("<I", data, first + 28)[0]
    body = first + 28 + 4 + name_len + 8  # the chunk's compressed records
    summary_start = struct.unpack_from("<Q", data, footer)[0]

    def damaged(name, offset, new_bytes):
        out = bytearray(data)
        out[offset:offset + len(new_bytes)] = new_bytes
        path = d / f"{name}.mcap"
        path.write_bytes(bytes(out))
        return path

    crc = struct.unpack_from("<I", data, first + 24)[0]
    return {
        "bad_chunk_crc": damaged("bad_chunk_crc", first + 24, struct.pack("<I", crc ^ 0x1)),
        "chunk_bit_flip": damaged("chunk_bit_flip", body + first_len // 2 - (body - first),
                                  bytes([data[body + first_len // 2 - (body - first)] ^ 0x40])),
        "chunk_size_lie": damaged("chunk_size_lie", first + 16,
                                  struct.pack("<Q", struct.unpack_from("<Q", data, first + 16)[0] + 7)),
        "bad_data_crc": damaged("bad_data_crc", data_end, struct.pack("<I", struct.unpack_from("<I", data, data_end)[0]
                                                                      ^ 0x10)),
        "bad_summary_crc": damaged("bad_summary_crc", summary_start + 20, bytes([data[summary_start + 20] ^ 0x01])),
        "footer_into_data": damaged("footer_into_data", footer, struct.pack("<Q", 16)),
        "bad_opcode": damaged("bad_opcode", data_end - 9, b"\x55"),  # the DataEnd record
    }


CORRUPT = {
    "bad_chunk_crc": "chunk at offset",
    "chunk_bit_flip": "chunk at offset",
    "chunk_size_lie": "not the",
    "bad_data_crc": "data section CRC mismatch",
    "bad_summary_crc": "summary CRC mismatch",
    "footer_into_data": "outside the summary section",
    "bad_opcode": "invalid record opcode",
}


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


@pytest.mark.parametrize("kind", sorted(CORRUPT))
def test_report_refuses_a_corrupted_file_in_one_line(bad_files, tmp_path, kind):
    """Each damage the file's checksums or structure reveal: one line, exit 2, nothing written; without the
    check several of these were reported as if whole (exit 0)."""
    path = bad_files[kind]
    out = run_cli("report", str(path), "--out", str(tmp_path / "report"), timeout=10)
    assert out.returncode == 2, out.stdout
    line = one_error_line(out)
    assert str(path) in line and "corrupted MCAP" in line and CORRUPT[kind] in line, line
    assert not (tmp_path / "report").exists()


def test_the_good_file_passes_every_check(bad_files):
    from stewart_vibration.mcap_log.integrity import verify_mcap

    layout = verify_mcap(bad_files["good"])
    assert layout.footer and layout.chunks >= 1


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
        (["fk", *["0.17"] * 6, "--tol", "-1"], "argument --tol: must be in [1e-15, 0.001] m, got -1"),
        (["fk", *["0.17"] * 6, "--tol", "0"], "argument --tol: must be in [1e-15, 0.001] m, got 0"),
        (["fk", *["0.17"] * 6, "--tol", "nan"], "argument --tol: 'nan' is not a finite number"),
        (["fk", *["0.17"] * 6, "--max-iter", "0"], "argument --max-iter: must be a whole number in 1..1000, got 0"),
        (["fk", "0.17", "0.17", "0.17", "0.17", "0.17", "-0.17"], "argument L: must be > 0"),
        (["ik", "0", "0", "0.16", "0", "0", "inf"], "argument Q: 'inf' is not a finite number"),
        (["validate-dynamics", "--clinical-duration", "-1"], "argument --clinical-duration: must be > 0, got -1"),
        (["validate-dynamics", "--paper-duration", "0"], "argument --paper-duration: must be > 0"),
        (["validate-dynamics", "--timestep", "-0.001"], "argument --timestep: must be > 0"),
        (["validate-dynamics", "--clinical-duration", "1e-9"], "shorter than 10 simulation steps"),
    ],
)
def test_bad_numbers_refused(capsys, args, words):
    code, out, lines = in_process(args, capsys)
    assert code == 2, out
    assert len(lines) == 1 and words in lines[0], lines


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


# -- every subcommand x every bad config-file class, in-process ----------------------------------------------

BOMB = "".join(f"l{i}: &l{i} [{', '.join([f'*l{i - 1}' if i else 'lol'] * 9)}]\n" for i in range(9))
FILE_CLASSES = {  # name -> (content or None for a special file, words of the refusal)
    "missing": (None, "No such file or directory"),
    "directory": (None, "a directory, not a regular file"),
    "fifo": (None, "a FIFO (named pipe), not a regular file"),
    "dev_zero": (None, "a character device, not a regular file"),
    "huge": (None, "more than the 1,000,000 a config file may have"),
    "not_utf8": (b"name: caf\xe9\n", "not UTF-8 text (byte 9"),
    "yaml_bomb": (BOMB.encode(), "expands to more than 100,000 values through its aliases"),
    "too_deep": (b"a: " + b"[" * 200_000, "nested deeper than 64 levels"),
    "recursive": (b"a: &a [1, *a]\n", "a recursive alias"),
    "duplicate_key": (b"a: 1\na: 2\n", "key 'a' appears twice"),
    "not_yaml": (b"a: [unclosed\n", "invalid YAML"),
    "unsafe_tag": (b"a: !!python/object/apply:os.system [echo]\n", "invalid YAML: could not determine a constructor"),
    "not_mapping": (b"- 1\n- 2\n", "the top level must be a mapping"),
}
# wrong types in a file of the right shape, per kind of config: (key, value, words)
WRONG_TYPES = {
    "robot": ("limits.stroke_max_m", "long", "'limits.stroke_max_m' must be a number, got 'long'"),
    "scenario": ("steps", [{"move_to": [0, 0, "up", 0, 0, 0]}], "'step 0 move_to[2]' must be a number, got 'up'"),
    "tissue": ("axial", {"stiffness_n_m": [1], "damping_n_s_m": 0}, "'axial.stiffness_n_m' must be a number"),
}
SHIPPED = {"robot": "robot.yaml", "scenario": "scenario_paper.yaml", "tissue": "tissue.yaml"}


@pytest.fixture(scope="module")
def hostile_files(tmp_path_factory):
    """name -> path of each FILE_CLASSES file, and "wrong_types_<kind>" of WRONG_TYPES."""
    d = tmp_path_factory.mktemp("hostile")
    files = {"missing": d / "missing.yaml", "directory": d / "a_folder.yaml", "fifo": d / "fifo.yaml",
             "dev_zero": Path("/dev/zero"), "huge": d / "huge.yaml"}
    files["directory"].mkdir()
    os.mkfifo(files["fifo"])
    with open(files["huge"], "wb") as f:
        f.truncate(5_000_000)
    for name, (content, _) in FILE_CLASSES.items():
        if content is not None:
            files[name] = d / f"{name}.yaml"
            files[name].write_bytes(content)
    for kind, (key, value, _) in WRONG_TYPES.items():
        tree = yaml.safe_load((CONFIG / SHIPPED[kind]).read_text())
        node = tree
        *parents, last = key.split(".")
        for part in parents:
            node = node[part]
        node[last] = value
        files[f"wrong_types_{kind}"] = d / f"wrong_{kind}.yaml"
        files[f"wrong_types_{kind}"].write_text(yaml.safe_dump(tree))
    return files


@pytest.fixture
def nothing_starts(monkeypatch):
    """`run` must refuse before the bring-up: constructing the suite's runner fails the test."""
    import stewart_vibration.nodes.suite_runner as suite_runner

    class Refuse:
        def __init__(self, *args, **kwargs):
            raise AssertionError("the run started its nodes: the input was not refused")

    monkeypatch.setattr(suite_runner, "SuiteRunner", Refuse)
    monkeypatch.delenv("ROS_DOMAIN_ID", raising=False)


def in_process(argv, capsys, timeout=DEADLINE_S):
    """(exit code, stdout, stderr lines) of ``stewart-vibration argv`` run in-process, in a thread so that a hang
    fails within ``timeout`` s; a warning counts as a stderr line (a process would print it there) and an
    exception escaping main() fails the test (a process would print a traceback)."""
    box: dict = {}

    def work():
        try:
            box["code"] = main([str(a) for a in argv])
        except SystemExit as exc:  # argparse's refusal
            box["code"] = exc.code
        except BaseException as exc:  # noqa: BLE001 - handed to the test
            box["error"] = exc

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        start = time.monotonic()
        thread = threading.Thread(target=work, daemon=True)
        thread.start()
        thread.join(timeout)
        elapsed = time.monotonic() - start
    assert not thread.is_alive(), f"{argv}: still running after {timeout} s"
    if "error" in box:
        raise AssertionError(f"{argv}: an exception escaped (a traceback)") from box["error"]
    out = capsys.readouterr()
    lines = out.err.strip().splitlines() + [f"warning: {w.message}" for w in caught]
    assert elapsed < timeout
    return box["code"], out.out, lines


def refused_in_one_line(argv, capsys, *words) -> str:
    code, _, lines = in_process(argv, capsys)
    assert code not in (0, None), (argv, code, lines)
    assert len(lines) == 1, (argv, lines)
    assert all(w in lines[0] for w in words), (argv, lines[0], words)
    return lines[0]


def robot_commands(out: Path, mcap: Path) -> dict:
    """Each subcommand that reads robot.yaml, with otherwise valid arguments."""
    return {"ik": ["ik", "0", "0", "0.16", "0", "0", "0"], "fk": ["fk", *["0.174"] * 6],
            "offline-scenario": ["offline-scenario"], "paper": ["paper", "--out", out / "paper"],
            "validate-dynamics": ["validate-dynamics"], "report": ["report", mcap, "--out", out / "report"],
            "run": ["run", "--out", out / "run"]}


ALL_CLASSES = sorted(FILE_CLASSES) + ["wrong_types"]


@pytest.mark.parametrize("kind", ALL_CLASSES)
@pytest.mark.parametrize("command", ["ik", "fk", "offline-scenario", "paper", "validate-dynamics", "report", "run"])
def test_every_subcommand_refuses_a_bad_robot_file_in_one_line(hostile_files, bad_files, nothing_starts, capsys,
                                                                tmp_path, command, kind):
    path = hostile_files["wrong_types_robot" if kind == "wrong_types" else kind]
    words = WRONG_TYPES["robot"][2] if kind == "wrong_types" else FILE_CLASSES[kind][1]
    argv = robot_commands(tmp_path, bad_files["good"])[command]
    # --robot before the subcommand and after it: the same option
    before = refused_in_one_line(["--robot", path, *argv], capsys, str(path), words)
    after = refused_in_one_line([*argv, "--robot", path], capsys, str(path), words)
    assert before == after and before.startswith("error: ConfigError: ")
    assert not (tmp_path / "report").exists() and not (tmp_path / "run").exists()  # nothing half-written


@pytest.mark.parametrize("kind", ["missing", "fifo", "not_utf8"])
def test_run_refuses_a_bad_plant_file_in_one_line(hostile_files, nothing_starts, capsys, tmp_path, kind):
    path = hostile_files[kind]
    refused_in_one_line(["run", "--plant", path, "--out", tmp_path / "run"], capsys, str(path.name),
                        FILE_CLASSES[kind][1])


@pytest.mark.parametrize("kind", ALL_CLASSES)
@pytest.mark.parametrize("option", ["--scenario", "--tissue"])
def test_run_refuses_a_bad_scenario_or_tissue_file_in_one_line(hostile_files, nothing_starts, capsys, tmp_path,
                                                               option, kind):
    which = "scenario" if option == "--scenario" else "tissue"
    path = hostile_files[f"wrong_types_{which}" if kind == "wrong_types" else kind]
    words = WRONG_TYPES[which][2] if kind == "wrong_types" else FILE_CLASSES[kind][1]
    if option == "--tissue" and kind == "missing":
        words = "not found (as given"
    refused_in_one_line(["run", option, path, "--out", tmp_path / "run"], capsys, str(path.name), words)


@pytest.mark.parametrize("kind", sorted(FILE_CLASSES) + ["robot_file", "no_pose"])
def test_run_refuses_a_bad_identification_file_in_one_line(hostile_files, nothing_starts, capsys, tmp_path, kind):
    """--identification: a file that is not an identification of the vibration units is refused before
    anything starts, naming the file and what is wrong with it."""
    if kind == "robot_file":
        path, words = CONFIG / "robot.yaml", "not a vibration identification file"
    elif kind == "no_pose":
        path, words = tmp_path / "no_pose.yaml", "identification file without 'pose'"
        path.write_text("kind: stewart_vibration/vibration_identification\n")
    else:
        path, words = hostile_files[kind], FILE_CLASSES[kind][1]
    refused_in_one_line(["run", "--identification", path, "--out", tmp_path / "run"], capsys, str(path.name), words)


@pytest.mark.parametrize("kind", ["fifo", "dev_zero"])
def test_mcap_inputs_that_would_block_are_refused(hostile_files, bad_files, capsys, tmp_path, kind):
    path = hostile_files[kind]
    refused_in_one_line(["report", path, "--out", tmp_path / "r"], capsys, f"RUN {path}", FILE_CLASSES[kind][1][:12])
    refused_in_one_line(["mcap-recover", path, tmp_path / "out.mcap"], capsys, f"IN {path}")
    refused_in_one_line(["mcap-recover", bad_files["good"], hostile_files["fifo"]], capsys, "OUT", "a FIFO")


@pytest.mark.parametrize(("command", "option"), [("paper", "--out"), ("report", "--out"),
                                                 ("validate-dynamics", "--out"), ("run", "--out")])
def test_an_output_folder_that_cannot_be_made_is_one_line(bad_files, nothing_starts, capsys, tmp_path, command,
                                                          option):
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    argv = {"paper": ["paper"], "report": ["report", bad_files["good"]], "validate-dynamics": ["validate-dynamics"],
            "run": ["run"]}[command]
    refused_in_one_line([*argv, option, blocker / "sub"], capsys, str(blocker))
    if command == "run":
        refused_in_one_line(["run", "--out", blocker], capsys, f"--out {blocker}: exists and is not a folder")


@pytest.mark.parametrize("left", ["run_20260101_000000.mcap", "metadata.yaml"])
def test_run_refuses_an_output_folder_that_holds_another_run(bad_files, nothing_starts, capsys, tmp_path, left):
    """An --out folder with another run's MCAP (or its bag metadata) is refused before anything starts: the
    summary reads every MCAP of the folder as this run's. An empty existing folder is taken."""
    earlier = tmp_path / "earlier"
    earlier.mkdir()
    (earlier / left).write_bytes(bad_files["good"].read_bytes() if left.endswith(".mcap") else b"x")
    refused_in_one_line(["run", "--out", earlier], capsys, f"--out {earlier}: already holds a run", left)
    empty = tmp_path / "empty"
    empty.mkdir()
    from stewart_vibration.cli.run_cmd import _output_folder
    assert _output_folder(str(empty)) == empty


# -- numbers and names ---------------------------------------------------------------------------------------

BAD_NUMBERS = ["nan", "inf", "-inf", "-1", "1e300", "abc", "", "0x10"]
NUMERIC_OPTIONS = {  # (argv before the value, argv after it, values that are valid here)
    "ik Q": (["ik"], ["0", "0.16", "0", "0", "0"], {"-1"}),
    "fk L": (["fk"], ["0.174"] * 5, set()),
    "fk --guess": (["fk", *["0.174"] * 6, "--guess"], ["0", "0.16", "0", "0", "0"], {"-1"}),
    "fk --tol": (["fk", *["0.174"] * 6, "--tol"], [], set()),
    "fk --max-iter": (["fk", *["0.174"] * 6, "--max-iter"], [], set()),
    "run --duration": (["run", "--duration"], [], set()),
    "run --real-time-factor": (["run", "--real-time-factor"], [], set()),
    "run --domain-id": (["run", "--domain-id"], [], set()),
    "run --plant-seed": (["run", "--plant-seed"], [], set()),
    "validate-dynamics --paper-duration": (["validate-dynamics", "--paper-duration"], [], set()),
    "validate-dynamics --clinical-duration": (["validate-dynamics", "--clinical-duration"], [], set()),
    "validate-dynamics --timestep": (["validate-dynamics", "--timestep"], [], set()),
}


@pytest.mark.parametrize("value", BAD_NUMBERS)
@pytest.mark.parametrize("option", sorted(NUMERIC_OPTIONS))
def test_every_numeric_option_refuses_bad_numbers_in_one_line(nothing_starts, capsys, tmp_path, option, value):
    before, after, valid = NUMERIC_OPTIONS[option]
    if value in valid:
        pytest.skip(f"{value} is a valid {option}")
    argv = [*before, value, *after] + (["--out", tmp_path / "run"] if before[0] == "run" else [])
    line = refused_in_one_line(argv, capsys)
    name = option.split(" ", 1)[1]
    # argparse names the option; a value it lets through is refused by the library, naming what it is
    assert f"argument {name}" in line or "error: " in line, line
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize(("value", "words"), [
    ("bad name", "'bad name' must be absolute"), ("/bad name", "the part 'bad name'"),
    ("/a//b", "an empty part"), ("/stewart/", "an empty part"), ("/1robot", "not starting with a digit"),
    ("/a-b", "only letters, digits and '_'"), ("", "must be absolute"), ("/" + "a" * 200, "at most 100"),
])
def test_run_refuses_a_bad_namespace_in_one_line(nothing_starts, capsys, value, words):
    refused_in_one_line(["run", "--namespace", value], capsys, "argument --namespace: not a ROS namespace", words)


def test_the_namespace_rule_agrees_with_rclpy():
    """runtime.suite.namespace_reason against rclpy's own validate_namespace (the reference), over names built
    from the characters and shapes that matter."""
    from rclpy.exceptions import InvalidNamespaceException
    from rclpy.validate_namespace import validate_namespace

    from stewart_vibration.runtime.suite import namespace_reason

    rng = np.random.default_rng(5)
    alphabet = list("ab_Z09/ -.~{}") + ["é"]
    names = ["/", "/stewart", "/a/b_c/D9", "/_x", "stewart", "//", "/a/", "/9", "/a b"]
    names += ["/" + "".join(rng.choice(alphabet, size=rng.integers(1, 12))) for _ in range(3000)]
    for name in names:
        try:
            validate_namespace(name)
            ros_ok = True
        except InvalidNamespaceException:
            ros_ok = False
        assert (namespace_reason(name) is None) == ros_ok, (name, namespace_reason(name))


def test_run_refuses_unknown_respawn_nodes_and_a_bad_ros_domain_id(nothing_starts, capsys, monkeypatch):
    refused_in_one_line(["run", "--respawn", "kinematics,ghost"], capsys, "argument --respawn: unknown node(s) "
                        "['ghost']")
    for env in ("abc", "1e300", "-3", "102"):
        monkeypatch.setenv("ROS_DOMAIN_ID", env)
        refused_in_one_line(["run"], capsys, f"$ROS_DOMAIN_ID '{env}'")


def test_refusals_as_a_user_sees_them_in_a_process(hostile_files):
    """The same refusals from a real `stewart-vibration` process: one line, exit 2, no traceback, in 10 s (the
    namespace gave a traceback; the FIFO hung forever and the bomb took 23 s)."""
    cases = [(["run", "--namespace", "bad name"], "not a ROS namespace"),
             (["run", "--scenario", hostile_files["fifo"]], "a FIFO"),
             (["run", "--scenario", hostile_files["yaml_bomb"]], "through its aliases"),
             (["--robot", hostile_files["dev_zero"], "ik", "0", "0", "0.16", "0", "0", "0"], "a character device")]
    for argv, words in cases:
        start = time.monotonic()
        out = run_cli(*map(str, argv), timeout=30)
        assert time.monotonic() - start < DEADLINE_S, argv
        assert out.returncode == 2, (argv, out.stdout, out.stderr)
        assert words in one_error_line(out), (argv, out.stderr)


# -- node executables ----------------------------------------------------------------------------------------

def node_modules() -> dict:
    from stewart_vibration.runtime.suite import OPTIONAL_NODES, SUITE_NODES

    return {**{n.name: n.module for n in SUITE_NODES + list(OPTIONAL_NODES.values())}, "mcap_replay": REPLAY}


def start_node(module: str, args, env=None, timeout=30):
    start = time.monotonic()
    out = subprocess.run([sys.executable, "-m", module, "--ros-args", *map(str, args)], capture_output=True,
                         text=True, timeout=timeout, env=env)
    return out, time.monotonic() - start


@pytest.mark.parametrize("node", sorted(node_modules()))
def test_every_node_refuses_a_missing_params_file_in_one_line(node):
    """`<node> --ros-args --params-file missing.yaml` gave rcl's RCLError traceback: the file is read safely
    before rclpy.init (no DDS is started), so it is one line and exit 2."""
    out, elapsed = start_node(node_modules()[node], ["--params-file", "missing.yaml"])
    assert out.returncode == 2 and elapsed < DEADLINE_S, (out.returncode, elapsed, out.stderr)
    assert "cannot read node parameter file missing.yaml: No such file or directory" in one_error_line(out)


@pytest.mark.parametrize("kind", ["fifo", "dev_zero", "yaml_bomb", "not_utf8"])
def test_a_params_file_that_would_block_or_explode_is_refused_before_rcl_reads_it(hostile_files, kind):
    out, elapsed = start_node("stewart_vibration.nodes.kinematics_node", ["--params-file", hostile_files[kind]])
    assert out.returncode == 2 and elapsed < DEADLINE_S, (out.returncode, elapsed, out.stderr)
    line = one_error_line(out)
    assert line.startswith("[FATAL] cannot start: ") and FILE_CLASSES[kind][1] in line, line


@pytest.mark.integration
@pytest.mark.parametrize(("node", "parameter", "kind"), [
    ("kinematics", "robot_config", "fifo"),
    ("kinematics", "tissue_config", "wrong_types_tissue"),
    ("vibration_planner", "robot_config", "yaml_bomb"),
    ("leg_force_estimator", "robot_config", "dev_zero"),
    ("hardware_emulator", "robot_config", "not_utf8"),
    ("hardware_emulator", "simulation_config", "too_deep"),
    ("hardware_emulator", "tissue_config", "length_1e-6"),
    ("hardware_emulator", "plant_config", "fifo"),
])
def test_a_node_refuses_a_bad_config_file_parameter_with_the_reason(hostile_files, ros_domain, tmp_path, node,
                                                                    parameter, kind):
    """The parameters that name a config file: the node exits 2 with the file and the reason (the emulator
    fails its configure transition, autostart makes that the exit), no traceback, within 10 s."""
    if kind == "length_1e-6":  # the tissue that killed the emulator's physics thread (4.7 MN, OverflowError)
        tree = yaml.safe_load((CONFIG / "tissue.yaml").read_text())
        tree["stiffening"]["length_m"] = 1e-6
        path = tmp_path / "tissue.yaml"
        path.write_text(yaml.safe_dump(tree))
        words = "'stiffening.length_m' = 1e-06 is outside"
    else:
        path = hostile_files[kind]
        words = WRONG_TYPES["tissue"][2] if kind.startswith("wrong_types") else FILE_CLASSES[kind][1]
    out, elapsed = start_node(node_modules()[node], ["-p", f"{parameter}:={path}"], env=ros_environment(ros_domain))
    assert out.returncode == 2 and elapsed < DEADLINE_S, (out.returncode, elapsed, out.stderr)
    assert "Traceback" not in out.stderr
    fatal = [line for line in out.stderr.splitlines() if line.startswith("[FATAL] cannot start: ")]
    assert len(fatal) == 1, out.stderr
    reason = fatal[0] if node != "hardware_emulator" else out.stderr  # the emulator logs why configure failed
    assert str(path) in reason and words in reason, out.stderr
