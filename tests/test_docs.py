"""The documentation stays a front door plus docs that exist: README at most 10 KB, every
relative link in README and docs/ pointing at a file of the repository, no SPEC citations."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def test_readme_is_a_front_door() -> None:
    assert (ROOT / "README.md").stat().st_size <= 10 * 1024


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
