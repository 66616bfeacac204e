"""docs/cli.md and docs/cli/*.md, the CLI reference, is what `python -m authn.cli.reference docs` generates from
the typer app today: a command, option or help text changed without regenerating fails here."""

from __future__ import annotations

from pathlib import Path

from authn.cli.reference import MAX_LINES, pages
from tests.lab_plugin import needs_lab

DOCS = Path(__file__).resolve().parents[1] / "docs"


@needs_lab
def test_the_cli_reference_is_current() -> None:
    want = pages()
    on_disk = {"cli.md", *(f"cli/{p.name}" for p in (DOCS / "cli").glob("*.md"))}
    assert on_disk == set(want), "regenerate: python -m authn.cli.reference docs"
    stale = [name for name, text in want.items() if (DOCS / name).read_text() != text]
    assert not stale, f"{stale} not current: python -m authn.cli.reference docs"


def test_every_command_and_option_is_in_it() -> None:
    import click

    from authn.cli import command
    from authn.cli.reference import _commands

    text = "\n".join(pages().values())
    for path, cmd in _commands(command()):
        assert f"## {' '.join(('authn', *path))}\n" in text, path
        for p in cmd.params:
            if isinstance(p, click.Option) and not p.hidden:
                assert f"`{p.opts[0]}`" in text, (path, p.opts)
    assert all(len(t.splitlines()) <= MAX_LINES < 300 for t in pages().values())
