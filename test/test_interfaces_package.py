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


def test_every_interface_file_is_named_in_the_docs():
    text = DOC.read_text()
    files = sorted(p for kind in ("msg", "srv", "action") for p in (INTERFACES / kind).glob(f"*.{kind}"))
    assert len(files) >= 8
    missing = [f"{p.parent.name}/{p.stem}" for p in files if f"{p.parent.name}/{p.stem}" not in text]
    assert not missing, f"docs/interfaces.md does not name {missing}"
