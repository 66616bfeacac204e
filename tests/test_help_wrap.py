"""Help pages wrap as prose at 80 columns: in every command's description a line ends only where
the next word would not have fitted (no ragged lines from the docstring's own line breaks)."""

from __future__ import annotations

import contextlib
import io
import re

import pytest

from authn.cli import command, main
from authn.cli.helptext import reflow

WIDTH = 80
CONTENT = WIDTH - 2  # rich pads the description one column either side
ITEM = re.compile(r"^\s*(?:[-*]|\d+[.)])\s")


def _commands(cmd=None, path=()):
    cmd = cmd or command()
    yield path, cmd
    for name, sub in sorted(getattr(cmd, "commands", {}).items()):
        yield from _commands(sub, (*path, name))


def _description(path: tuple[str, ...]) -> list[list[str]]:
    """The paragraphs of a command's help page above its first panel, as rendered lines."""
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main([*path, "-h"]) == 0, path
    text = buf.getvalue().split("╭")[0]
    body = text.split("Usage:", 1)[1].split("\n", 1)[1]
    paragraphs, current = [], []
    for line in body.splitlines():
        if line.strip():
            current.append(line.strip())
        elif current:
            paragraphs.append(current)
            current = []
    return paragraphs + ([current] if current else [])


def test_every_help_description_wraps_greedily(monkeypatch):
    monkeypatch.setenv("COLUMNS", str(WIDTH))
    ragged = []
    for path, _ in _commands():
        for par in _description(path):
            for line, nxt in zip(par, par[1:]):
                if not ITEM.match(nxt) and len(line) + 1 + len(nxt.split()[0]) <= CONTENT:
                    ragged.append((" ".join(path) or "authn", line, nxt))
    assert not ragged, ragged[:5]


@pytest.mark.parametrize("text, want", [
    ("First.\n\nOne paragraph\nover two lines.", "First.\n\nOne paragraph over two lines."),
    ("T.\n\nSteps:\n1. one\n2. two", "T.\n\nSteps:\n1. one\n2. two"),
    ("T.\n\nExample: authn x \\\n  --y 1", "T.\n\nExample: authn x --y 1"),
    ("T.\n\n\b\nkept\nas is", "T.\n\n\b\nkept\nas is"),
])
def test_reflow(text, want):
    assert reflow(text) == want
