"""Where a node may write a file a client asked for (pure python): an action goal from the network names the
path, so the node writes only YAML files, only in a folder it can write, and never over a file that is not
one of its own kind (an identification, a calibrated robot file): a goal cannot clobber anything else. Files are
written whole or not at all (``write_text_whole``)."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from .errors import ConfigError, InvalidInputError
from .safe_yaml import load_yaml

SUFFIXES = (".yaml", ".yml")


def writable_output(path: str, what: str, own_kind: Callable[[dict], bool]) -> Path:
    """``path`` made absolute, if this node may write its ``what`` there: a .yaml or .yml name in an existing,
    writable folder, and either no file yet or a YAML mapping ``own_kind`` recognises (one written before).

    Raises:
        InvalidInputError: naming the path and what is wrong with it.
    """
    given = Path(path).expanduser()
    if given.is_symlink():  # a link may point anywhere: never written through
        raise InvalidInputError(f"output_path {path!r} is a symbolic link: not overwritten")
    target = given.resolve()
    if target.suffix not in SUFFIXES:
        raise InvalidInputError(f"output_path {path!r}: the {what} is a YAML file (a name ending in .yaml or .yml)")
    if target.is_dir() or not os.access(target.parent, os.W_OK):
        raise InvalidInputError(f"output_path {path!r}: not a file this node can write ({target.parent} must "
                                "exist and be writable)")
    if target.exists():
        try:
            tree = load_yaml(target, what)
        except ConfigError as exc:
            raise InvalidInputError(f"output_path {path!r} exists and is not a {what} ({exc}): not overwritten") \
                from None
        if not own_kind(tree):
            raise InvalidInputError(f"output_path {path!r} exists and is not a {what}: not overwritten")
    return target


def write_text_whole(path: str | os.PathLike, text: str) -> Path:
    """``text`` to ``path`` whole or not at all: written to a temporary file beside it, then renamed over it (a
    reader never sees half a file, a failed write leaves the old one). Returns the path."""
    target = Path(path)
    partial = target.with_name(f".{target.name}.partial")
    partial.write_text(text)
    os.replace(partial, target)
    return target
