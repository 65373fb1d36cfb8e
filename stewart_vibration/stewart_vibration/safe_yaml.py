"""Config files read safely (pure python): the one YAML reader of every config the package loads.

A config path can be anything a user types: a FIFO (that would block a plain ``open`` forever), a device
such as /dev/zero (that a plain ``read`` never finishes), a directory, a huge file, bytes that are not
UTF-8, or a YAML "bomb" whose few anchors expand into billions of nodes once any code walks the values.
``load_yaml`` refuses each of these with one ConfigError line naming the file and the reason:

- only regular files, told by ``fstat`` on a descriptor opened with O_NONBLOCK (so a FIFO never hangs);
- at most ``max_bytes`` (MAX_BYTES), read bounded (a file that grows while read is still refused);
- strict UTF-8;
- one YAML document, checked before any value is built: nesting at most MAX_DEPTH and at most MAX_NODES
  nodes as written (from the parser's events), then composed into nodes and checked again as expanded
  through its aliases (what any consumer walks), with no recursive alias and no duplicate key in a
  mapping; only then built by ``yaml.SafeLoader``'s constructor (safe tags only);
- a mapping at the top level when one is expected (an empty file reads as ``{}``).
"""

from __future__ import annotations

import os
import reprlib
import stat

import yaml

from .errors import ConfigError

MAX_BYTES = 1_000_000  # a config file of the package is a few kB; 1 MB leaves room for long scenarios
MAX_NODES = 100_000  # scalars, lists and mappings after alias expansion (robot.yaml has ~100)
MAX_DEPTH = 64  # nesting of lists and mappings (robot.yaml has 4)

_Loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)  # libyaml's parser when PyYAML was built with it
_SHORT = reprlib.Repr()
_SHORT.maxstring, _SHORT.maxother, _SHORT.maxlist, _SHORT.maxdict, _SHORT.maxlevel = 60, 60, 8, 6, 3


def short_repr(value) -> str:
    """``repr`` of a config value cut to about a line (an error message must not print a whole file)."""
    return _SHORT.repr(value)


def _file_kind(mode: int) -> str:
    for test, name in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a regular file"


def special_file_reason(path: str | os.PathLike) -> str | None:
    """What ``path`` is if it exists and is neither a regular file nor a directory ("a FIFO (named pipe)",
    "a character device", ...), else None. ``stat`` only: it never opens (so never blocks on) the file."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return None
    return None if stat.S_ISREG(mode) or stat.S_ISDIR(mode) else _file_kind(mode)


def read_config_bytes(path: str | os.PathLike, what: str, max_bytes: int = MAX_BYTES) -> bytes:
    """The bytes of the regular file ``path``, at most ``max_bytes`` of them.

    Args:
        path: the file.
        what: what the file is ("robot config", "scenario", ...), for the error message.
        max_bytes: the size limit (bytes).

    Returns:
        The file's content.

    Raises:
        ConfigError: the file is missing or unreadable, is not a regular file (directory, FIFO, device,
            socket: said which), or is larger than ``max_bytes``.
    """
    flags = os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        raise ConfigError(f"cannot read {what} {path}: {exc.strerror or exc}") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise ConfigError(f"cannot read {what} {path}: {_file_kind(info.st_mode)}, not a regular file")
        if info.st_size > max_bytes:
            raise ConfigError(f"cannot read {what} {path}: {info.st_size:,} bytes, more than the "
                              f"{max_bytes:,} a config file may have")
        chunks, size = [], 0
        while size <= max_bytes:  # bounded even if the file grows while it is read
            chunk = os.read(fd, max_bytes + 1 - size)
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    except OSError as exc:
        raise ConfigError(f"cannot read {what} {path}: {exc.strerror or exc}") from None
    finally:
        os.close(fd)
    if size > max_bytes:
        raise ConfigError(f"cannot read {what} {path}: more than the {max_bytes:,} bytes a config file may have")
    return b"".join(chunks)


def _check_events(text: str, where: str) -> None:
    """Refuse nesting deeper than MAX_DEPTH and more than MAX_NODES nodes as written, from libyaml's event
    stream (iterative: its recursive composer would crash the interpreter on a deep enough nesting)."""
    depth = count = 0
    for event in yaml.parse(text, Loader=_Loader):
        if isinstance(event, (yaml.SequenceStartEvent, yaml.MappingStartEvent)):
            depth += 1
            if depth > MAX_DEPTH:
                raise ConfigError(f"{where}: nested deeper than {MAX_DEPTH} levels; refused")
        elif isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
            depth -= 1
        if isinstance(event, yaml.NodeEvent):
            count += 1
            if count > MAX_NODES:
                raise ConfigError(f"{where}: more than {MAX_NODES:,} values; refused")


def _check_nodes(root: yaml.Node, where: str) -> None:
    """Refuse a node graph that expands past MAX_NODES or nests deeper than MAX_DEPTH through its aliases,
    contains a recursive alias, or a mapping with a duplicate key. Iterative and linear in the distinct
    nodes (aliases share them)."""
    expanded: dict[int, tuple[int, int]] = {}  # id(node) -> (node count, height) with every alias expanded
    on_path: set[int] = set()
    stack: list[tuple[yaml.Node, int, bool]] = [(root, 1, False)]
    while stack:
        node, depth, children_done = stack.pop()
        key = id(node)
        if children_done:
            on_path.discard(key)
            below = [expanded[id(c)] for c in _children(node)]
            expanded[key] = (1 + sum(n for n, _ in below), 1 + max((h for _, h in below), default=0))
            if expanded[key][0] > MAX_NODES:
                raise ConfigError(f"{where}: expands to more than {MAX_NODES:,} values through its aliases "
                                  "(&anchor / *alias); refused")
        elif key in on_path:
            raise ConfigError(f"{where}: a recursive alias (an anchor used inside itself); refused")
        elif key in expanded or depth > MAX_DEPTH:  # seen through another alias: only its depth here counts
            if depth - 1 + expanded.get(key, (0, 1))[1] > MAX_DEPTH:
                raise ConfigError(f"{where}: nested deeper than {MAX_DEPTH} levels through its aliases; refused")
        else:
            if isinstance(node, yaml.MappingNode):
                _check_duplicate_keys(node, where)
            on_path.add(key)
            stack.append((node, depth, True))
            stack.extend((child, depth + 1, False) for child in _children(node))


def _children(node: yaml.Node) -> list[yaml.Node]:
    if isinstance(node, yaml.SequenceNode):
        return list(node.value)
    if isinstance(node, yaml.MappingNode):
        return [n for pair in node.value for n in pair]
    return []


def _check_duplicate_keys(node: yaml.MappingNode, where: str) -> None:
    seen = set()
    for key_node, _ in node.value:
        if isinstance(key_node, yaml.ScalarNode):
            if key_node.value in seen:
                raise ConfigError(f"{where}: key '{short_repr(key_node.value)[1:-1]}' appears twice "
                                  f"(line {key_node.start_mark.line + 1})")
            seen.add(key_node.value)


def _yaml_problem(exc: yaml.YAMLError) -> str:
    """One line for a YAML error (PyYAML's own text spans several lines with a snippet of the file)."""
    if isinstance(exc, yaml.MarkedYAMLError):
        mark = exc.problem_mark or exc.context_mark
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark is not None else ""
        text = ", ".join(str(part) for part in (exc.context, exc.problem) if part) or "syntax error"
        return " ".join(text.split()) + where
    return " ".join(str(exc).split())


def parse_yaml(text: str, where: str):
    """The one YAML document in ``text``, checked as ``load_yaml`` describes (no file access).

    Args:
        text: the YAML text.
        where: what and where the text is ("robot config config/robot.yaml"), for the error message.

    Returns:
        The parsed value (None for an empty document).

    Raises:
        ConfigError: invalid YAML, more than one document, too many nodes through aliases, too deep, a
            recursive alias, a duplicate key, or a tag ``yaml.SafeLoader`` does not build.
    """
    loader = _Loader(text)
    try:
        _check_events(text, where)
        node = loader.get_single_node()
        if node is None:
            return None
        _check_nodes(node, where)
        return loader.construct_document(node)
    except yaml.YAMLError as exc:
        raise ConfigError(f"{where}: invalid YAML: {_yaml_problem(exc)}") from None
    except RecursionError:
        raise ConfigError(f"{where}: nested too deeply; refused") from None
    finally:
        loader.dispose()


def load_yaml(path: str | os.PathLike, what: str, mapping: bool = True, max_bytes: int = MAX_BYTES):
    """Read the YAML config file ``path`` safely (see the module docstring).

    Args:
        path: the file.
        what: what the file is ("robot config", "tissue config", "scenario", ...), for the error message.
        mapping: the top level must be a mapping (an empty file is ``{}``).
        max_bytes: the file's size limit (bytes).

    Returns:
        The parsed document: a dict when ``mapping``.

    Raises:
        ConfigError: one line naming the file and the reason (``read_config_bytes``, ``parse_yaml``, invalid
            UTF-8 with the byte offset, or a top level that is not a mapping).
    """
    data = read_config_bytes(path, what, max_bytes)
    where = f"{what} {path}"
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{where}: not UTF-8 text (byte {exc.start}: {data[exc.start:exc.start + 1]!r})") from None
    tree = parse_yaml(text, where)
    if mapping and tree is None:
        return {}
    if mapping and not isinstance(tree, dict):
        raise ConfigError(f"{where}: the top level must be a mapping (key: value lines), got "
                          f"{type(tree).__name__} {short_repr(tree)}")
    return tree


__all__ = ["MAX_BYTES", "MAX_DEPTH", "MAX_NODES", "load_yaml", "parse_yaml", "read_config_bytes", "short_repr",
           "special_file_reason"]
