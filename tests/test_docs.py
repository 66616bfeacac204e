"""The documentation stays a front door plus a reference a user can look things up in: README at
most 10 KB, docs pages under 300 lines, laboratory commands only on the one page that reproduces
our figures (the write-ups live in lab/reports), every relative link in README, docs/ and the
laboratory's reports pointing at a file of the repository, no SPEC citations."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")
DOCS = sorted([*(ROOT / "docs").glob("*.md"), *(ROOT / "docs" / "cli").glob("*.md")])
PAGES = [ROOT / "README.md", *DOCS, ROOT / "lab" / "README.md", *sorted((ROOT / "lab" / "reports").glob("*.md"))]
MAX_DOC_LINES = 300
#: the one user page that may name laboratory commands
REPRODUCE = ROOT / "docs" / "reproduce.md"


def test_readme_is_a_front_door() -> None:
    assert (ROOT / "README.md").stat().st_size <= 10 * 1024


def test_every_docs_page_is_under_300_lines() -> None:
    long = {p.name: n for p in DOCS if (n := len(p.read_text().splitlines())) >= MAX_DOC_LINES}
    assert not long, long


def test_laboratory_commands_only_on_the_reproduce_page() -> None:
    offenders = [p.name for p in DOCS if p != REPRODUCE and re.search(r"python -m lab\b", p.read_text())]
    assert not offenders, offenders
    assert "python -m lab." in REPRODUCE.read_text()


def test_every_relative_link_resolves() -> None:
    broken = []
    for page in PAGES:
        for target in LINK.findall(page.read_text()):
            if "://" in target or target.startswith("mailto:"):
                continue
            if not (page.parent / target).exists():
                broken.append(f"{page.relative_to(ROOT)} -> {target}")
    assert not broken, broken


#: The phrase the old contract's citations used, built so that this file does not contain it.
OLD_CITATION = " ".join(("SPEC", "section"))


def test_no_spec_section_citations() -> None:
    offenders = [str(p.relative_to(ROOT)) for pkg in ("authn", "registry", "signatures", "docs", "tests")
                 for p in (ROOT / pkg).rglob("*") if p.suffix in (".py", ".md") and p.is_file()
                 and OLD_CITATION in p.read_text(errors="ignore")]
    assert not offenders, offenders
