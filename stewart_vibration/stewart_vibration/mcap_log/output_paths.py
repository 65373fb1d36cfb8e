"""Where the recorder may write (pure filesystem): its bag folder and the names of its files.

``file_pattern`` names one file inside the bag folder. It may hold only the placeholders of
``FILE_PATTERN_FIELDS``, each replaced as plain text (never ``str.format``: a pattern is user text):

- ``{stamp}``: local time of the file's start, ``YYYYmmdd_HHMMSS``;
- ``{node}``: the recorder's node name (ROS names are ``[A-Za-z0-9_]``);
- ``{index}``: the file's number in this recorder's bag, from 1.

The name it gives must be a plain file name: letters, digits, ``._+-`` only (no separator, no
``..``, not hidden), ending in ``.mcap``, at most ``MAX_NAME_BYTES`` long.

``output_dir`` is the bag folder itself:

- a relative path is taken under the working directory and may not climb out of it (no ``..``); its
  missing folders are created;
- an absolute path must be an existing directory, or a new folder directly inside one (the user names a
  place that is there on purpose; no tree of folders is made outside the working directory);
- it must not be a file, nor hold a ``metadata.yaml`` that this recorder did not write (a foreign bag:
  its metadata would be overwritten), nor be a runs root (a folder with a ``latest`` link, whose run
  folders are bags of their own).

Every refusal is an ``InvalidInputError`` that names the parameter and says why.
"""

from __future__ import annotations

import re
from pathlib import Path, PurePath

from ..errors import InvalidInputError
from .bag_metadata import METADATA_FILE, read_metadata_yaml

FILE_PATTERN_FIELDS = ("stamp", "node", "index")
MAX_NAME_BYTES = 200
RECORDED_BY_KEY = "recorded_by"  # custom_data key of the metadata.yaml the recorder writes
RECORDED_BY = "stewart_vibration mcap_recorder"
_NAME = re.compile(r"^[A-Za-z0-9_+\-][A-Za-z0-9_.+\-]*$")
_PLACEHOLDER = re.compile(r"\{([^{}]*)\}")


def check_file_pattern(pattern: str) -> None:
    """Refuse a ``file_pattern`` that is not a plain file name with known placeholders (InvalidInputError)."""
    file_name(pattern, stamp="20000101_000000", node="mcap_recorder", index=1)


def file_name(pattern: str, *, stamp: str, node: str, index: int) -> str:
    """The file name ``pattern`` gives (its placeholders replaced as plain text).

    Args:
        pattern: the ``file_pattern`` parameter.
        stamp: local time ``YYYYmmdd_HHMMSS``.
        node: the node's name.
        index: the file's number in the bag (1, 2, ...).

    Returns:
        A plain file name ending in ``.mcap``.

    Raises:
        InvalidInputError: an unknown placeholder or a stray brace, a separator, ``..``, a hidden or
            empty name, a character outside ``[A-Za-z0-9_.+-]``, no ``.mcap`` suffix, or too long.
    """
    if not isinstance(pattern, str) or not pattern:
        raise InvalidInputError("file_pattern: must be a non-empty file name such as 'run_{stamp}.mcap'")
    unknown = [f for f in _PLACEHOLDER.findall(pattern) if f not in FILE_PATTERN_FIELDS]
    if unknown:
        raise InvalidInputError(f"file_pattern {pattern!r}: unknown placeholder {{{unknown[0]}}}; the known ones "
                                f"are {', '.join('{' + f + '}' for f in FILE_PATTERN_FIELDS)}")
    name = pattern
    for field, value in (("stamp", stamp), ("node", node), ("index", str(int(index)))):
        name = name.replace("{" + field + "}", value)
    if "{" in name or "}" in name:
        raise InvalidInputError(f"file_pattern {pattern!r}: a brace that is not part of a placeholder")
    if "/" in name or "\\" in name or name in (".", ".."):
        raise InvalidInputError(f"file_pattern {pattern!r}: must name a file inside output_dir (no path "
                                "separator, no '..'); set output_dir to choose the folder")
    if ".." in name:
        raise InvalidInputError(f"file_pattern {pattern!r}: '..' is not allowed in a file name")
    if not _NAME.match(name):
        raise InvalidInputError(f"file_pattern {pattern!r} gives {name!r}: only letters, digits and '._+-' are "
                                "allowed, and the name may not start with '.'")
    if not name.endswith(".mcap") or name == ".mcap":
        raise InvalidInputError(f"file_pattern {pattern!r} gives {name!r}: the name must end in '.mcap'")
    if len(name.encode()) > MAX_NAME_BYTES:
        raise InvalidInputError(f"file_pattern {pattern!r}: the name is longer than {MAX_NAME_BYTES} bytes")
    return name


def bag_folder(output_dir: str, cwd: str | Path) -> Path:
    """The bag folder ``output_dir`` names (absolute), checked; not created.

    Args:
        output_dir: the ``output_dir`` parameter (relative to ``cwd``, or absolute).
        cwd: the working directory relative paths are taken under.

    Returns:
        The folder's absolute path (relative ones lexically under ``cwd``).

    Raises:
        InvalidInputError: empty, a NUL byte, ``..`` in a path, an absolute path whose parent is not an
            existing directory, a file, a foreign bag, or a runs root (``check_bag_folder``).
    """
    if not isinstance(output_dir, str) or not output_dir.strip():
        raise InvalidInputError("output_dir: must name a folder")
    if "\0" in output_dir:
        raise InvalidInputError("output_dir: contains a NUL byte")
    given = PurePath(output_dir)
    if ".." in given.parts:
        raise InvalidInputError(f"output_dir {output_dir!r}: '..' is not allowed (a relative output_dir may not "
                                "climb out of the working directory; give an absolute path instead)")
    if given.is_absolute():
        folder = Path(given)
        if folder.exists() and not folder.is_dir():
            raise InvalidInputError(f"output_dir {output_dir!r} is a file, not a folder")
        if not folder.is_dir() and not folder.parent.is_dir():
            raise InvalidInputError(f"output_dir {output_dir!r}: {folder.parent} does not exist (an absolute "
                                    "output_dir must be an existing directory or a new folder in one)")
    else:
        folder = Path(cwd).resolve() / given
        for part in [folder, *folder.parents]:
            if part.exists() and not part.is_dir():
                raise InvalidInputError(f"output_dir {output_dir!r}: {part} is a file, not a folder")
            if part == Path(cwd).resolve():
                break
    check_bag_folder(folder)
    return folder


def check_bag_folder(folder: Path) -> None:
    """Refuse a folder that holds a foreign bag's metadata.yaml, or that is a runs root (InvalidInputError)."""
    if (folder / "latest").is_symlink():
        raise InvalidInputError(f"output_dir {str(folder)!r} is a runs folder (it has a 'latest' link): each run "
                                "folder in it is a bag of its own; leave output_dir empty for a new one")
    meta = folder / METADATA_FILE
    if meta.exists() and not written_by_recorder(folder):
        raise InvalidInputError(f"output_dir {str(folder)!r} holds a {METADATA_FILE} this recorder did not write "
                                "(another bag): choose another folder")


def written_by_recorder(folder: Path) -> bool:
    """Whether ``folder/metadata.yaml`` exists and carries the recorder's mark (custom_data recorded_by)."""
    try:
        custom = read_metadata_yaml(folder).get("custom_data") or {}
    except Exception:  # noqa: BLE001 - missing, unreadable or malformed: not ours
        return False
    return isinstance(custom, dict) and custom.get(RECORDED_BY_KEY) == RECORDED_BY


def listed_files(folder: Path) -> list[str]:
    """The file names ``folder/metadata.yaml`` lists ([] if it has none or it cannot be read)."""
    try:
        return [PurePath(str(p)).name for p in read_metadata_yaml(folder)["relative_file_paths"]]
    except Exception:  # noqa: BLE001 - no usable list
        return []
