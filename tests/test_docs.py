"""The documentation: a guide that speaks of what the tool does now, apart from the
development notes, and a site that the README points at.

The guide and reference pages (``docs/**/*.md`` outside ``docs/notes/``) carry no issue
numbers: the study notes, dated measurements and issue references live in
``docs/notes/``, which the guide links where a figure comes from. The site itself is built
with warnings as errors by ``.ci/run`` (``sphinx-build -W``), not here."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"
ISSUE_REFERENCE = re.compile(r"\bissues? [0-9]", re.IGNORECASE)


def guide_pages() -> list[Path]:
    return sorted(p for p in DOCS.rglob("*.md") if "notes" not in p.relative_to(DOCS).parts
                  and "_build" not in p.relative_to(DOCS).parts)


def test_guide_pages_have_no_issue_references():
    pages = guide_pages()
    assert len(pages) > 20 and DOCS / "index.md" in pages
    found = {str(p.relative_to(REPO)): m.group(0) for p in pages
             for m in [ISSUE_REFERENCE.search(p.read_text(encoding="utf-8"))] if m}
    assert not found, f"issue references belong in docs/notes/, not in the guide: {found}"


def test_the_pattern_finds_issue_references():
    for text in ("(issue 29)", "Issue 22's done-when", "issues 21 and 28"):
        assert ISSUE_REFERENCE.search(text), text
    for text in ("no issue here", "tissue 3", "issue: the 20 materials"):
        assert not ISSUE_REFERENCE.search(text), text


def test_development_notes_have_their_own_index_and_every_page_is_listed():
    index = (DOCS / "notes" / "index.md").read_text(encoding="utf-8")
    assert "Development notes" in index
    for page in sorted((DOCS / "notes").glob("*.md")):
        if page.name != "index.md":
            assert f"\n{page.stem}\n" in index, f"{page.name} is not in the notes' toctree"


def test_readme_links_the_sites_entry_page_and_how_to_build_it():
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    assert "](docs/index.md)" in readme
    assert "sphinx-build -W --keep-going -b html docs docs/_build/html" in readme
    ci = (REPO / ".ci" / "run").read_text(encoding="utf-8")
    assert '".[docs]"' in ci and "sphinx-build -W" in ci


def test_readme_shows_every_command_of_the_help():
    """The README's first commands (the install line and the "Use" block) name every
    command that ``brdfkit --help`` lists."""
    import re

    from brdfkit.cli import COMMANDS

    readme = (REPO / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```bash\n(.*?)```", readme.split("## Your data")[0], re.S)
    shown = set(re.findall(r"\bbrdfkit (\w+)", "".join(blocks)))
    assert sorted(set(COMMANDS) - shown) == []
