"""The suite's interfaces package as its users meet it: the outcome table of docs/interfaces.md is the one of
Outcome.msg (codes, names and meanings), the built Python types carry the same constants, and every .msg,
.srv and .action file is named in the docs."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
INTERFACES = ROOT / "stewart_vibration_interfaces"
DOC = ROOT / "docs" / "interfaces.md"


def msg_constants(path: Path) -> dict[str, tuple[int, str]]:
    """{name: (value, comment)} of the integer constants of a .msg file, read from its text."""
    found = {}
    for line in path.read_text().splitlines():
        m = re.match(r"\s*u?int\d+\s+([A-Z][A-Z0-9_]*)\s*=\s*(\d+)\s*(?:#\s*(.*))?$", line)
        if m:
            found[m.group(1)] = (int(m.group(2)), (m.group(3) or "").strip())
    return found


def doc_outcome_rows() -> dict[str, tuple[int, str]]:
    """{name: (code, meaning)} of the outcome table in docs/interfaces.md."""
    section = DOC.read_text().split("## Outcome codes", 1)[1].split("\n## ", 1)[0]
    rows = {}
    for line in section.splitlines():
        m = re.match(r"\|\s*(\d+)\s*\|\s*`([A-Z_0-9]+)`\s*\|\s*(.*?)\s*\|$", line)
        if m:
            rows[m.group(2)] = (int(m.group(1)), m.group(3))
    return rows


def test_the_documented_outcome_table_is_the_message_s():
    constants = msg_constants(INTERFACES / "msg" / "Outcome.msg")
    assert len(constants) >= 20 and len({v for v, _ in constants.values()}) == len(constants)  # codes unique
    assert doc_outcome_rows() == constants


def test_the_built_outcome_type_has_the_file_s_constants():
    from stewart_vibration_interfaces.msg import Outcome

    constants = msg_constants(INTERFACES / "msg" / "Outcome.msg")
    assert {name: getattr(Outcome, name) for name in constants} == {n: v for n, (v, _) in constants.items()}
    assert Outcome().code == Outcome.UNDEFINED != Outcome.SUCCEEDED  # an unset code never reads as success


def test_the_pure_outcome_table_is_the_message_s():
    """The core's ROS-free table (messages.outcome_codes) holds exactly Outcome.msg's names and codes."""
    from stewart_vibration.messages.outcome_codes import CODES, NAMES

    constants = msg_constants(INTERFACES / "msg" / "Outcome.msg")
    assert CODES == {n: v for n, (v, _) in constants.items()}
    assert all(CODES[NAMES[code]] == code for code in NAMES)


def test_every_interface_file_is_named_in_the_docs():
    text = DOC.read_text()
    files = sorted(p for kind in ("msg", "srv", "action") for p in (INTERFACES / kind).glob(f"*.{kind}"))
    assert len(files) >= 8
    missing = [f"{p.parent.name}/{p.stem}" for p in files if f"{p.parent.name}/{p.stem}" not in text]
    assert not missing, f"docs/interfaces.md does not name {missing}"


def outcome_names_in_the_package() -> set[str]:
    """Every outcome name the package gives: ``outcome = "NAME"`` of an error class, the first argument of
    RefusedError(...) and outcome(...), and an all-caps argument of abort(...) / _finish(...)."""
    import ast

    names = set()
    for path in (ROOT / "stewart_vibration" / "stewart_vibration").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Assign) and any(getattr(t, "id", "") == "outcome" for t in node.targets) and \
                    isinstance(node.value, ast.Constant) and isinstance(node.value.value, str):
                names.add(node.value.value)
            elif isinstance(node, ast.Call):
                func = getattr(node.func, "id", None) or getattr(node.func, "attr", None)
                args = [c.value for a in node.args for c in ([a.body, a.orelse] if isinstance(a, ast.IfExp) else [a])
                        if isinstance(c, ast.Constant) and isinstance(c.value, str)]
                if func in ("RefusedError", "outcome") and node.args and isinstance(node.args[0], ast.Constant):
                    names.add(node.args[0].value)
                elif func in ("abort", "_finish"):
                    names |= {a for a in args if re.fullmatch(r"[A-Z][A-Z_]+", a)}
    return names


def test_every_outcome_the_package_gives_is_in_the_table():
    names = outcome_names_in_the_package()
    assert {"INTERNAL_ERROR", "BUSY", "NOT_READY", "LIMIT_EXCEEDED", "CANCELED", "SUCCEEDED"} <= names  # it looks
    unknown = names - set(msg_constants(INTERFACES / "msg" / "Outcome.msg"))
    assert not unknown, f"outcome names not in Outcome.msg: {sorted(unknown)}"
