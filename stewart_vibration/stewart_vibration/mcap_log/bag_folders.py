"""The recorder's bag folders: where its next file goes, the file's name, and the rosbag2 metadata.yaml that
lists the files finished there. Pure (no ROS): the recorder node passes its parameters and logs what it gets.

A bag folder is a rosbag2 bag directory. When a recording finishes, ``finish`` writes ``folder/metadata.yaml``
(rosbag2 version 9, as ``ros2 bag record`` does) listing the files this recorder wrote there (one per
start..stop, like rosbag2's splits), so ``ros2 bag info/play folder`` and ``rosbags.rosbag2.Reader(folder)``
open it. While a file is being written the folder has no metadata.yaml. A metadata.yaml an earlier recorder
wrote in the folder (it carries the recorder's mark in custom_data) is taken over: its complete files stay
listed beside the new ones. A folder with a metadata.yaml the recorder did not write is refused. After a crash
(SIGKILL) the folder has none until ``stewart-vibration mcap-recover`` rebuilds the cut file and writes one.
Other files in the folder (logs/, report/, summary.json) are ignored by bag readers.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

from .bag_metadata import BagFile, bag_metadata, remove_metadata_yaml, write_metadata_yaml
from .output_paths import (
    RECORDED_BY,
    RECORDED_BY_KEY,
    bag_folder,
    check_bag_folder,
    check_file_pattern,
    file_name,
    listed_files,
    written_by_recorder,
)
from .reader import bag_file_of


class BagFolders:
    """The bag folders one recorder writes to, and the files it finished (or took over) in each."""

    def __init__(self, cwd: Path, new_run_folder: Callable[[], Path]):
        self.cwd = cwd  # what a relative output_dir is under
        self.new_run_folder = new_run_folder  # makes the recorder's own folder, for output_dir ""
        self.files: dict[Path, list[BagFile]] = {}  # folder -> files finished there (taken over or ours)
        self.own_folder: Path | None = None  # the run folder output_dir "" made

    def folder(self, output_dir: str) -> Path:
        """The bag folder of the next file: ``output_dir`` (checked again: the disk may have changed; created if
        missing), or for "" a run folder of its own (``new_run_folder``).

        Raises:
            InvalidInputError: output_dir is refused (``output_paths.bag_folder``).
            OSError: the folder cannot be created.
        """
        if output_dir:
            folder = bag_folder(output_dir, self.cwd)
            folder.mkdir(parents=True, exist_ok=True)
            return folder
        if self.own_folder is None or not self.own_folder.is_dir():
            self.own_folder = self.new_run_folder()
        check_bag_folder(self.own_folder)
        return self.own_folder

    def next_path(self, folder: Path, pattern: str, node_name: str) -> Path:
        """The next file in ``folder`` named by ``pattern`` ({stamp}, {node}, {index}); an existing name gets _n.

        Raises:
            InvalidInputError: the pattern is refused (``output_paths.check_file_pattern``).
        """
        check_file_pattern(pattern)
        index = len(self.files.get(folder, [])) + 1
        name = file_name(pattern, stamp=time.strftime("%Y%m%d_%H%M%S"), node=node_name, index=index)
        path = folder / name
        n = 1
        while path.exists():
            path = path.with_name(f"{Path(name).stem}_{n}{Path(name).suffix}")
            n += 1
        return path

    def take_over(self, folder: Path) -> int | None:
        """Adopt the complete files an earlier recorder's metadata.yaml lists in ``folder`` (their count; None when
        there was nothing to adopt), then remove the metadata.yaml (none while a file is written)."""
        adopted = None
        if folder not in self.files and written_by_recorder(folder):
            entries = [bag_file_of(folder / name) for name in listed_files(folder)]
            self.files[folder] = [e for e in entries if e is not None]
            adopted = len(self.files[folder])
        remove_metadata_yaml(folder)
        return adopted

    def finish(self, folder: Path, finished: BagFile | None) -> tuple[Path, int]:
        """List ``finished`` (None: a file whose write failed, left out) with the folder's other files in its
        metadata.yaml; returns (its path, the files it lists).

        Raises:
            OSError: the metadata.yaml cannot be written.
        """
        files = self.files.setdefault(folder, [])
        if finished is not None:
            files.append(finished)
        return write_metadata_yaml(folder, bag_metadata(files, {RECORDED_BY_KEY: RECORDED_BY})), len(files)
