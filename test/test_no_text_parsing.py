"""No node learns what another node did by reading its text: outcomes are typed codes (Outcome.msg), so no
module of the package matches a substring or a regular expression on a message, an answer's text or a log
line. Regular expressions are allowed only where they validate names and values against a grammar
(ALLOWED_REGEX: each says what it checks)."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "stewart_vibration" / "stewart_vibration"
# attributes that hold text for people: a message, a log line, a reason
TEXT_FIELDS = {"message", "msg", "reason", "text", "detail", "stdout", "stderr", "ramp_reason", "event_reason",
               "event_text", "fault_reason"}
TEXT_SEARCHES = {"startswith", "endswith", "find", "rfind", "index", "rindex", "split", "rsplit", "partition",
                 "rpartition", "count"}
ALLOWED_REGEX = {
    "mcap_log/bag_metadata.py": "topic names in a rosbag2 metadata.yaml",
    "mcap_log/msg_definitions.py": "field types and type names of .msg files",
    "mcap_log/output_paths.py": "file names and their {placeholders}",
    "messages/fields.py": "numbers written as text and control characters in received fields",
    "runtime/suite.py": "node and parameter names of the suite's table",
}


def text_matches(source: str) -> list[tuple[int, str]]:
    """(line, code) of every substring test or search on a text attribute and every ``re`` call in ``source``."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Compare) and any(isinstance(op, (ast.In, ast.NotIn)) for op in node.ops):
            if any(isinstance(c, ast.Attribute) and c.attr in TEXT_FIELDS for c in node.comparators):
                found.append((node.lineno, ast.unparse(node)))
        if isinstance(node, ast.Compare) and isinstance(node.left, ast.Attribute) and node.left.attr in TEXT_FIELDS \
                and any(isinstance(op, (ast.Eq, ast.NotEq, ast.In, ast.NotIn)) for op in node.ops):
            found.append((node.lineno, ast.unparse(node)))  # text compared with a known text: a reason read back
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            func = node.func
            if func.attr in TEXT_SEARCHES and isinstance(func.value, ast.Attribute) and func.value.attr in TEXT_FIELDS:
                found.append((node.lineno, ast.unparse(node)))
            if isinstance(func.value, ast.Name) and func.value.id == "re":
                found.append((node.lineno, ast.unparse(node)))
    return found


def test_the_check_finds_each_kind_of_text_match():
    source = '''
import re
if "rejected leg trajectory" in status.message: pass
if msg.msg.startswith("recording"): pass
found = re.match(r"recording to (\\S+)", line)
if answer.reason.split(":")[0] == "x": pass
if "ok" not in response.message: pass
if report.ramp_reason in STRUT_STOPS: pass
if self.diagnostics.message == "waiting for legs/joint_states": pass
'''
    assert sorted(line for line, _ in text_matches(source)) == [3, 4, 5, 6, 7, 8, 9]
    assert not text_matches("if name in NAMES: pass\nif message.startswith('force guard'): pass\n"
                            "if report.ramp_cause in STRUT_STOP_CAUSES: pass\nif report.event == 'refused': pass\n")


def test_no_module_matches_text_of_another_node():
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        relative = path.relative_to(PACKAGE).as_posix()
        hits = [(line, code) for line, code in text_matches(path.read_text())
                if not (relative in ALLOWED_REGEX and code.startswith("re."))]
        if hits:
            found[relative] = hits
    assert not found, f"text matched where a typed code belongs: {found}"


def test_every_allowed_regular_expression_module_exists_and_uses_one():
    for relative in ALLOWED_REGEX:
        source = (PACKAGE / relative).read_text()
        assert any(code.startswith("re.") for _, code in text_matches(source)), relative
