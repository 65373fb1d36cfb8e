"""One folder per run, runs/latest pointing at the newest (a repeated main job used to pile its .mcap files
into one runs/latest, so `mcap-recover runs/latest` found several and refused)."""

from __future__ import annotations

import errno
import os

import pytest

from stewart_vibration.runtime.run_folders import new_run_folder


def test_each_run_gets_its_own_folder_and_latest_follows(tmp_path):
    runs = tmp_path / "runs"
    first = new_run_folder(runs, now=1_700_000_000.0)
    second = new_run_folder(runs, now=1_700_000_000.0)  # same second: a suffix, not the same folder
    assert first != second and first.is_dir() and second.is_dir()
    assert first.parent == runs and second.name == first.name + "_2"
    latest = runs / "latest"
    assert latest.is_symlink() and latest.resolve() == second.resolve()
    assert not (runs / "latest").readlink().is_absolute()  # relative: the runs folder can be moved
    (second / "run_x.mcap").write_bytes(b"x")
    assert (latest / "run_x.mcap").read_bytes() == b"x"


def test_an_older_real_latest_folder_is_kept(tmp_path):
    runs = tmp_path / "runs"
    old = runs / "latest"
    old.mkdir(parents=True)
    (old / "run_old.mcap").write_bytes(b"old")
    folder = new_run_folder(runs)
    kept = [p for p in runs.iterdir() if p.is_dir() and not p.is_symlink() and p != folder]
    assert len(kept) == 1 and (kept[0] / "run_old.mcap").read_bytes() == b"old"
    assert (runs / "latest").resolve() == folder.resolve()


def test_a_reserved_summary_is_written_on_a_full_disk(tmp_path):
    from small_filesystem import small_filesystem

    from stewart_vibration.runtime.run_folders import reserve_file, write_reserved

    with small_filesystem(tmp_path / "small", 256 * 1024) as fs:
        reserve_file(fs / "summary.json", 64 * 1024)
        fd = os.open(fs / "filler", os.O_WRONLY | os.O_CREAT)  # the recording fills the disk
        try:
            while True:
                os.write(fd, b"x" * 4096)
        except OSError as exc:
            assert exc.errno == errno.ENOSPC
        finally:
            os.close(fd)
        with pytest.raises(OSError):
            (fs / "other.json").write_text("{}")  # full: nothing new fits
        assert write_reserved(fs / "summary.json", '{"ok": true}') == fs / "summary.json"
        assert (fs / "summary.json").read_text() == '{"ok": true}'
        assert not (fs / ".summary.json.reserve").exists()
