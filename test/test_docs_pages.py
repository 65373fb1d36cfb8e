"""The README is a short front page and the docs pages hold the rest: the README stays short, starts with the
two commands, links every docs page, and no relative link or image of the README or a docs page points at a
file that does not exist (the link checks run on the text, so they are cheap)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PAGES = sorted((ROOT / "docs").glob("*.md"))
README_MAX_LINES = 250

FENCED = re.compile(r"^```.*?^```[ \t]*$", re.MULTILINE | re.DOTALL)
CODE_SPAN = re.compile(r"`[^`\n]*`")
# [text](target) and ![alt](target), the text possibly wrapped over lines; an optional "title" after the target
LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")


def link_targets(markdown: str) -> list[str]:
    """Every link and image target of ``markdown`` outside code blocks and code spans."""
    prose = CODE_SPAN.sub("", FENCED.sub("", markdown))
    return LINK.findall(prose)


def broken_links(doc: Path, root: Path = ROOT) -> list[str]:
    """The relative targets of ``doc`` (http(s), mailto and #anchors within the page left out) that name no file
    or folder inside ``root``; a target's own #anchor is not checked."""
    broken = []
    for target in link_targets(doc.read_text(encoding="utf-8")):
        if re.match(r"[a-z][a-z0-9+.-]*:", target, re.IGNORECASE) or target.startswith("#"):
            continue  # http(s)://, mailto: ... and anchors on the same page
        path = (doc.parent / target.split("#", 1)[0]).resolve()
        if not path.exists() or not path.is_relative_to(root.resolve()):
            broken.append(f"{doc.relative_to(root)}: {target}")
    return broken


def test_the_readme_is_a_short_front_page():
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines (at most {README_MAX_LINES})"
    # the title, then at once the two commands
    assert lines[0].startswith("# ") and lines[1] == "" and lines[2] == "```bash", lines[:3]
    assert lines[3].startswith("./tools/main ") and lines[4].startswith("./tools/test ") and lines[5] == "```"


def test_the_readme_links_every_docs_page():
    linked = {(ROOT / t.split("#", 1)[0]).resolve() for t in link_targets(README.read_text(encoding="utf-8"))}
    missing = [p.name for p in PAGES if p.resolve() not in linked]
    assert PAGES and not missing, f"docs pages the README does not link: {missing}"


def test_every_relative_link_and_image_names_a_file_that_exists():
    targets = sum((link_targets(doc.read_text(encoding="utf-8")) for doc in [README, *PAGES]), [])
    assert len(targets) >= len(PAGES) and any(t.endswith(".png") for t in targets)  # the check sees links
    broken = sum((broken_links(doc) for doc in [README, *PAGES]), [])
    assert not broken, "links to nothing:\n" + "\n".join(broken)


def test_the_link_check_sees_what_it_looks_for(tmp_path):
    root = tmp_path / "repo"
    root.mkdir()
    doc = root / "page.md"
    doc.write_text("see [a page\nwrapped](other.md#part) and ![pic](pic.png \"title\"), [web](https://x.org/a),\n"
                   "[here](#anchor), `[code](nothing.md)`\n```\n[fenced](nothing.md)\n```\n")
    assert link_targets(doc.read_text()) == ["other.md#part", "pic.png", "https://x.org/a", "#anchor"]
    assert broken_links(doc, root) == ["page.md: other.md#part", "page.md: pic.png"]
    (root / "other.md").write_text("")
    (root / "pic.png").write_bytes(b"")
    assert broken_links(doc, root) == []
    (tmp_path / "outside.md").write_text("")
    doc.write_text("[up](../outside.md)")
    assert broken_links(doc, root) == ["page.md: ../outside.md"]  # a file outside the repository counts too
