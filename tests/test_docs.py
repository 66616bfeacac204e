"""The documentation stays a front door plus a reference a user can look things up in: README at
most 10 KB, docs pages under 300 lines, every relative link in README, docs/ and the laboratory's
reports pointing at a file of the repository (and a link into the results pages at one of their
headings), no SPEC citations. The reference says what the system does, not when it was measured:
a measured figure lives, with its command, date and software, on the results pages (docs/results.md
and docs/results/*.md), which `python -m lab.results docs` generates from lab/results/*.toml; no
other docs page carries a dated stamp. Laboratory commands (`python -m lab...`) appear on the page
that reproduces our figures and on the results pages, which must name the command of each result;
the write-ups live in lab/reports."""

from __future__ import annotations

import re
from pathlib import Path

from lab.results import COMMAND, anchor, pages, topics

ROOT = Path(__file__).resolve().parents[1]
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")
DOCS = sorted([*(ROOT / "docs").glob("*.md"), *(ROOT / "docs" / "cli").glob("*.md"),
               *(ROOT / "docs" / "results").glob("*.md")])
PAGES = [ROOT / "README.md", *DOCS, ROOT / "lab" / "README.md", *sorted((ROOT / "lab" / "reports").glob("*.md"))]
MAX_DOC_LINES = 300
#: the user page that reproduces our figures
REPRODUCE = ROOT / "docs" / "reproduce.md"
#: the generated results pages: the only docs pages with dates, and with laboratory commands beside reproduce.md
RESULTS = {ROOT / "docs" / name for name in pages()}
#: a calendar date not part of an ISO 8601 timestamp (`2026-01-01T00:00:00Z` is an example value)
DATE = re.compile(r"\b(?:19|20)\d\d-[01]\d-[0-3]\d\b(?!T)")
#: code (a fenced block, an inline span, a help text's `Example:` line): example values, not stamps
CODE = re.compile(r"```.*?```|`[^`\n]*`|^Example\b.*$", re.S | re.M)
#: dates that are facts of a format, not measurement stamps: the Unix and F3411 epochs, the earliest start_time
FORMAT_DATES = {"1970-01-01", "2019-01-01", "2000-01-01"}


def test_readme_is_a_front_door() -> None:
    assert (ROOT / "README.md").stat().st_size <= 10 * 1024


def test_every_docs_page_is_under_300_lines() -> None:
    long = {p.name: n for p in DOCS if (n := len(p.read_text().splitlines())) >= MAX_DOC_LINES}
    assert not long, long


def test_laboratory_commands_only_on_the_reproduce_and_results_pages() -> None:
    allowed = {REPRODUCE, *RESULTS}
    offenders = [p.name for p in DOCS if p not in allowed and re.search(r"python -m lab\b", p.read_text())]
    assert not offenders, offenders
    assert "python -m lab." in REPRODUCE.read_text()


def test_no_dated_stamps_outside_the_results_pages() -> None:
    stamped = {f"{p.relative_to(ROOT)}:{d}" for p in [ROOT / "README.md", *DOCS] if p not in RESULTS
               for d in DATE.findall(CODE.sub("", p.read_text())) if d not in FORMAT_DATES}
    assert not stamped, f"move these measurements to lab/results/*.toml ({COMMAND}): {sorted(stamped)}"


def test_the_results_pages_are_current() -> None:
    want = pages()
    on_disk = {"results.md", *(f"results/{p.name}" for p in (ROOT / "docs" / "results").glob("*.md"))}
    assert on_disk == set(want), f"regenerate: {COMMAND}"
    stale = [name for name, text in want.items() if (ROOT / "docs" / name).read_text() != text]
    assert not stale, f"{stale} not current: {COMMAND}"


def test_links_into_the_results_pages_name_a_result() -> None:
    headings = {name: {anchor(h) for h in re.findall(r"^#+ (.+)$", text, re.M)} for name, text in pages().items()}
    broken = []
    for page in PAGES:
        for target, frag in re.findall(r"\]\(([^)#\s]*results(?:\.md|/[\w-]+\.md))#([^)\s]+)\)", page.read_text()):
            name = (page.parent / target).resolve().relative_to(ROOT / "docs").as_posix()
            if frag not in headings.get(name, set()):
                broken.append(f"{page.relative_to(ROOT)} -> {target}#{frag}")
    assert not broken, broken


def _headings(page: Path) -> set[str]:
    text = page.read_text()
    return {anchor(h) for h in re.findall(r"^#+ (.+)$", text, re.M)} | set(re.findall(r'<a id="([^"]+)"', text))


def test_every_result_names_the_reference_section_it_measures() -> None:
    missing = []
    for topic in topics():
        for r in topic.results:
            page, _, frag = r.described.partition("#")
            if frag and frag not in _headings(ROOT / "docs" / page):
                missing.append(f"{topic.name}: {r.title} -> {r.described}")
    assert not missing, missing


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
