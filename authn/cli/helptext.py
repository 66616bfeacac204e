"""Help text as prose: a command's docstring reflowed so the terminal, not the source, wraps it.

typer (0.25, rich output) keeps a docstring's single line breaks after its first paragraph, so
each source line would also end a terminal line, and a paragraph wider than the terminal would
come out ragged (a long line wrapped, then a short one). Each paragraph's lines are joined here;
list items and `\\b` paragraphs (click's "keep as written") keep their lines.
"""

from __future__ import annotations

import inspect
import re

__all__ = ["reflow"]

#: a line that starts a list item (`- `, `* `, `1. `, `2) `): it keeps its own line
_ITEM = re.compile(r"^\s*(?:[-*]|\d+[.)])\s")


def reflow(text: str | None) -> str | None:
    """`text` with the single line breaks inside each paragraph replaced by spaces (a trailing
    shell continuation `\\` dropped with its break); paragraphs stay apart."""
    if not text:
        return text
    return "\n\n".join(p if p.startswith("\b") else _join(p) for p in inspect.cleandoc(text).split("\n\n"))


def _join(paragraph: str) -> str:
    lines: list[str] = []
    for line in paragraph.split("\n"):
        if lines and not _ITEM.match(line):
            lines[-1] = f"{lines[-1].rstrip().removesuffix(chr(92)).rstrip()} {line.strip()}"
        else:
            lines.append(line.rstrip())
    return "\n".join(lines)
