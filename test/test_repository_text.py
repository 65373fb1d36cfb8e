"""The repository's text speaks for itself: no document, comment or configuration points outside the
repository (a sibling folder, an absolute path of the machine it was written on) or names a ticket number
instead of saying why."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SKIPPED = {".git", ".venv", "build", "install", "log", "runs", "__pycache__", ".pytest_cache", ".mypy_cache",
           ".ruff_cache", "node_modules"}
TEXT = {".py", ".md", ".yaml", ".yml", ".json", ".js", ".html", ".css", ".sh", ".cfg", ".ini", ".toml", ".txt",
        ".xml", ".msg", ".srv", ".action", ".launch", ""}
TICKET = re.compile(r"\bissues? #?\d+", re.IGNORECASE)
OUTSIDE = re.compile(r"\.\./shared|/work/|shared/paper|\bDESIGN\.md|\bREVIEW\.md")


def repository_text_files() -> list[Path]:
    """Every text file of the checkout (by suffix; scripts without one too), outside build and cache folders
    and the hidden folders tools leave (.hypothesis, .venv, ...; .ci is the project's)."""
    found = []
    for path in ROOT.rglob("*"):
        parts = path.relative_to(ROOT).parts
        hidden = parts[0].startswith(".") and parts[0] not in (".ci", ".github")  # tools' caches, not ours
        if hidden or any(part in SKIPPED for part in parts) or not path.is_file():
            continue
        if path.suffix in TEXT and path.stat().st_size < 2_000_000:
            found.append(path)
    return found


def offending_lines(pattern: re.Pattern, paths) -> list[str]:
    lines = []
    for path in paths:
        try:
            text = path.read_text(encoding="utf-8")
        except (UnicodeDecodeError, OSError):
            continue
        lines += [f"{path.relative_to(ROOT)}:{n}: {line.strip()}" for n, line in enumerate(text.splitlines(), 1)
                  if pattern.search(line)]
    return lines


@pytest.fixture(scope="module")
def text_files():
    files = repository_text_files()
    assert any(p.name == "README.md" for p in files) and any(p.suffix == ".py" for p in files)
    return [p for p in files if p != Path(__file__).resolve()]  # this file spells the patterns out


@pytest.mark.parametrize("what, pattern", [("a ticket number", TICKET), ("a place outside the repository", OUTSIDE)])
def test_no_text_names_a_ticket_or_points_outside_the_repository(text_files, what, pattern):
    found = offending_lines(pattern, text_files)
    assert not found, f"{len(found)} line(s) name {what}:\n" + "\n".join(found[:20])


def test_the_checks_see_what_they_look_for(tmp_path):
    """The patterns catch the forms they are for and leave ordinary prose alone."""
    ticket = "issue"  # spelt apart here so that this file does not carry the form it forbids
    for bad in (f"# why ({ticket} 17)", f"see {ticket}s 11, 13", f"{ticket.title()} #4: fixed", "../shared/paper/x.pdf",
                "/work/main/config", "the corrected math in REVIEW.md"):
        assert TICKET.search(bad) or OUTSIDE.search(bad), bad
    for fine in ("no issue with that", f"t{ticket} 12 N", "../../x is refused", "beside this file"):
        assert not (TICKET.search(fine) or OUTSIDE.search(fine)), fine
