"""The one config reader (safe_yaml.load_yaml) against what a hostile or careless user can give it: every
refusal is one ConfigError line naming the file and the reason, and nothing blocks, reads forever or
expands. Accepted files read exactly as ``yaml.safe_load`` reads them (the reference)."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest
import yaml

from stewart_vibration.errors import ConfigError
from stewart_vibration.safe_yaml import MAX_BYTES, MAX_DEPTH, MAX_NODES, load_yaml, special_file_reason

CONFIG = Path(__file__).resolve().parents[1] / "stewart_vibration" / "config"
BOMB = "".join(f"l{i}: &l{i} [{', '.join([f'*l{i - 1}' if i else 'lol'] * 9)}]\n" for i in range(9)) + "top: *l8\n"


def refusal(path, what="robot config", **kwargs) -> str:
    """The ConfigError text of load_yaml(path), checked to be one line naming the file."""
    with pytest.raises(ConfigError) as caught:
        load_yaml(path, what, **kwargs)
    text = str(caught.value)
    assert "\n" not in text and str(path) in text and what in text, text
    return text


def finishes(call, timeout=5.0):
    """call() run in a thread; fails if it has not returned (or raised) within ``timeout`` s."""
    box: dict = {}

    def work():
        try:
            box["value"] = call()
        except BaseException as exc:  # noqa: BLE001 - handed to the test
            box["error"] = exc

    thread = threading.Thread(target=work, daemon=True)
    thread.start()
    thread.join(timeout)
    assert not thread.is_alive(), f"still running after {timeout} s"
    return box


@pytest.mark.parametrize("name", sorted(p.name for p in CONFIG.glob("*.yaml")))
def test_every_config_file_reads_as_yaml_safe_load_reads_it(name):
    path = CONFIG / name
    assert load_yaml(path, "config") == yaml.safe_load(path.read_text())


def test_aliases_within_the_budget_read_as_yaml_safe_load_reads_them(tmp_path):
    path = tmp_path / "anchors.yaml"
    path.write_text("defaults: &d {stiffness_n_m: 1.0, damping_n_s_m: 2.0}\naxial: *d\nlateral: *d\n"
                    "pose: &p [0, 0, 0.16, 0, 0, 0]\nposes: [*p, *p, *p]\n")
    assert load_yaml(path, "x") == yaml.safe_load(path.read_text())


def test_a_yaml_bomb_is_refused_without_being_expanded(tmp_path):
    path = tmp_path / "bomb.yaml"
    path.write_text(BOMB)
    tree = yaml.safe_load(BOMB)  # the reference: it composes fine, but walking it would visit 9^9 strings
    assert len(tree["top"]) == 9 and tree["top"][0][0] is tree["top"][1][0]
    assert "expands to more than" in refusal(path) and f"{MAX_NODES:,}" in refusal(path)


def test_a_bomb_just_inside_the_budget_is_accepted(tmp_path):
    # 9^4 = 6,561 leaves plus their lists: under MAX_NODES, and the expanded tree is what safe_load builds
    text = "".join(f"l{i}: &l{i} [{', '.join([f'*l{i - 1}' if i else '1'] * 9)}]\n" for i in range(4))
    path = tmp_path / "small.yaml"
    path.write_text(text)
    assert load_yaml(path, "x") == yaml.safe_load(text)


def test_a_recursive_alias_is_refused(tmp_path):
    path = tmp_path / "loop.yaml"
    path.write_text("a: &a [1, *a]\n")
    assert isinstance(yaml.safe_load(path.read_text())["a"][1], list)  # PyYAML builds a list holding itself
    assert "recursive alias" in refusal(path)


def test_nesting_is_limited_through_aliases_too(tmp_path):
    ok = tmp_path / "ok.yaml"
    ok.write_text("a: " + "[" * (MAX_DEPTH - 1) + "]" * (MAX_DEPTH - 1) + "\n")  # the mapping is level 1
    assert load_yaml(ok, "x") == yaml.safe_load(ok.read_text())
    deep = tmp_path / "deep.yaml"
    deep.write_text("a: " + "[" * MAX_DEPTH + "]" * MAX_DEPTH + "\n")
    assert "nested deeper than" in refusal(deep)
    chain = tmp_path / "chain.yaml"  # every line at depth 2, but each alias adds a level
    chain.write_text("a0: &a0 [1]\n" + "".join(f"a{i}: &a{i} [*a{i - 1}]\n" for i in range(1, MAX_DEPTH + 2)))
    assert "nested deeper than" in refusal(chain) and "aliases" in refusal(chain)


def test_a_million_open_brackets_do_not_crash_the_interpreter(tmp_path):
    """libyaml's recursive composer overflows the C stack on deep nesting (a segfault, not an exception): the
    loader refuses from the parser's events first. In a subprocess, so a crash is a failure, not the end of
    the test run."""
    path = tmp_path / "brackets.yaml"
    path.write_text("[" * 999_000)
    code = ("import sys; from stewart_vibration.safe_yaml import load_yaml; from stewart_vibration.errors import "
            f"ConfigError\ntry:\n    load_yaml({str(path)!r}, 'x')\nexcept ConfigError as exc:\n    print(exc)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert "nested deeper than" in out.stdout


def test_a_fifo_is_refused_at_once_even_with_no_writer(tmp_path):
    fifo = tmp_path / "fifo.yaml"
    os.mkfifo(fifo)
    box = finishes(lambda: load_yaml(fifo, "scenario"))  # a plain open() would wait for a writer forever
    assert isinstance(box.get("error"), ConfigError), box
    assert "a FIFO (named pipe), not a regular file" in str(box["error"])


def test_devices_directories_and_missing_files_are_refused_with_what_they_are(tmp_path):
    box = finishes(lambda: load_yaml("/dev/zero", "x"))  # read() of /dev/zero never ends
    assert "a character device, not a regular file" in str(box["error"])
    assert "a directory, not a regular file" in refusal(tmp_path)
    assert "No such file or directory" in refusal(tmp_path / "missing.yaml")
    assert special_file_reason("/dev/null") == "a character device"
    assert special_file_reason(tmp_path) is None and special_file_reason(tmp_path / "missing") is None


def test_size_limit(tmp_path):
    exact = tmp_path / "exact.yaml"
    exact.write_text("a: 1\n#" + "x" * (MAX_BYTES - 7) + "\n")
    assert exact.stat().st_size == MAX_BYTES and load_yaml(exact, "x") == {"a": 1}
    big = tmp_path / "big.yaml"
    with open(big, "wb") as f:
        f.truncate(MAX_BYTES + 1)  # sparse: the size says it all
    assert f"{MAX_BYTES + 1:,} bytes, more than the {MAX_BYTES:,}" in refusal(big)
    assert "more than" in refusal(exact, max_bytes=100)


def test_invalid_utf8_names_the_byte(tmp_path):
    path = tmp_path / "latin1.yaml"
    path.write_bytes("name: café\n".encode("latin-1"))
    assert "not UTF-8 text (byte 9: b'\\xe9')" in refusal(path)


@pytest.mark.parametrize(("text", "words"), [
    ("geometry: [unclosed\n", "invalid YAML:"),
    ("a: 1\n---\nb: 2\n", "invalid YAML: expected a single document in the stream, but found another document (line 2"),
    ("a: !!python/object/apply:os.system [echo]\n", "invalid YAML: could not determine a constructor"),
    ("a: 1\nb: 2\na: 3\n", "key 'a' appears twice (line 3)"),
    ("- 1\n- 2\n", "the top level must be a mapping (key: value lines), got list [1, 2]"),
    ("just text\n", "the top level must be a mapping (key: value lines), got str 'just text'"),
])
def test_bad_yaml_is_one_line_with_the_reason(tmp_path, text, words):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    assert words in refusal(path)


def test_an_empty_file_is_an_empty_mapping_and_lists_are_allowed_when_asked(tmp_path):
    empty = tmp_path / "empty.yaml"
    empty.write_text("# nothing\n")
    assert load_yaml(empty, "x") == {}
    listed = tmp_path / "list.yaml"
    listed.write_text("- 1\n- 2\n")
    assert load_yaml(listed, "x", mapping=False) == [1, 2]
