"""Where the recorder may write (mcap_log.output_paths): file names from a fixed set of placeholders
replaced as text, bag folders confined to the working directory or an existing absolute directory,
never a foreign bag's folder."""

from __future__ import annotations

import pytest

from stewart_vibration.errors import InvalidInputError
from stewart_vibration.mcap_log.bag_metadata import BagFile, bag_metadata, write_metadata_yaml
from stewart_vibration.mcap_log.output_paths import (
    RECORDED_BY,
    RECORDED_BY_KEY,
    bag_folder,
    check_file_pattern,
    file_name,
    written_by_recorder,
)

FIELDS = {"stamp": "20240102_030405", "node": "mcap_recorder", "index": 3}


def test_placeholders_are_replaced_as_plain_text():
    assert file_name("run_{stamp}.mcap", **FIELDS) == "run_20240102_030405.mcap"
    assert file_name("{node}-{index}_{stamp}.mcap", **FIELDS) == "mcap_recorder-3_20240102_030405.mcap"
    assert file_name("fixed.mcap", **FIELDS) == "fixed.mcap"


@pytest.mark.parametrize(("pattern", "words"), [
    ("{node.__class__.__mro__}.mcap", "unknown placeholder {node.__class__.__mro__}"),
    ("{0}.mcap", "unknown placeholder {0}"),
    ("{}.mcap", "unknown placeholder {}"),
    ("run_{stamp!r}.mcap", "unknown placeholder"),
    ("run_{stamp.mcap", "a brace that is not part of a placeholder"),
    ("run_}.mcap", "a brace"),
    ("../escape.mcap", "no path separator"),
    ("sub/run.mcap", "no path separator"),
    ("/tmp/abs.mcap", "no path separator"),
    ("..\\win.mcap", "no path separator"),
    ("a..b.mcap", "'..' is not allowed"),
    (".hidden.mcap", "may not start with '.'"),
    ("run name.mcap", "only letters, digits"),
    ("run\0.mcap", "only letters, digits"),
    ("run_{stamp}.txt", "must end in '.mcap'"),
    ("", "non-empty"),
    ("x" * 300 + ".mcap", "longer than"),
])
def test_hostile_patterns_are_refused_with_the_reason(pattern, words):
    with pytest.raises(InvalidInputError) as err:
        check_file_pattern(pattern)
    assert words in str(err.value)


def test_a_relative_folder_stays_under_the_working_directory(tmp_path):
    assert bag_folder("runs/a/b", tmp_path) == tmp_path.resolve() / "runs" / "a" / "b"
    for bad in ("../out", "runs/../../out", "a/../b", f"{tmp_path}/../x"):
        with pytest.raises(InvalidInputError, match="may not climb out"):
            bag_folder(bad, tmp_path)


def test_an_absolute_folder_must_be_an_existing_directory_or_a_new_one_in_it(tmp_path):
    assert bag_folder(str(tmp_path), "/") == tmp_path
    assert bag_folder(str(tmp_path / "new"), "/") == tmp_path / "new"
    with pytest.raises(InvalidInputError, match="does not exist"):
        bag_folder(str(tmp_path / "missing" / "deeper"), "/")
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    with pytest.raises(InvalidInputError, match="is a file"):
        bag_folder(str(blocker), "/")
    with pytest.raises(InvalidInputError, match="is a file"):
        bag_folder("a_file/sub", tmp_path)
    with pytest.raises(InvalidInputError, match="NUL"):
        bag_folder("a\0b", tmp_path)
    with pytest.raises(InvalidInputError, match="must name a folder"):
        bag_folder("", tmp_path)


def test_a_foreign_bag_and_a_runs_root_are_refused(tmp_path):
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    write_metadata_yaml(foreign, bag_metadata([BagFile("x.mcap")]))  # as another tool writes it: no mark
    assert not written_by_recorder(foreign)
    with pytest.raises(InvalidInputError, match="did not write"):
        bag_folder(str(foreign), "/")
    (foreign / "metadata.yaml").write_text(": not yaml [")
    with pytest.raises(InvalidInputError, match="did not write"):
        bag_folder(str(foreign), "/")
    ours = tmp_path / "ours"
    ours.mkdir()
    write_metadata_yaml(ours, bag_metadata([BagFile("x.mcap")], {RECORDED_BY_KEY: RECORDED_BY}))
    assert written_by_recorder(ours) and bag_folder(str(ours), "/") == ours
    runs = tmp_path / "runs"
    (runs / "run_1").mkdir(parents=True)
    (runs / "latest").symlink_to("run_1")
    with pytest.raises(InvalidInputError, match="runs folder"):
        bag_folder("runs", tmp_path)
    assert bag_folder("runs/latest", tmp_path) == tmp_path.resolve() / "runs" / "latest"
