"""A line and a two-column table as rich lays them out on a pipe, without importing rich.

`authn check` prints its human output (a headline, then a label/value table) through rich on a
terminal, in colour. Piped, rich writes the same text with no colour at all, and importing rich
is then most of what the human output costs over `--json`. `render` writes that uncoloured
text itself: rich's word wrapping (words keep the spaces after them, a word longer than a line
is folded) at rich's console width, the label column as wide as its longest label plus one
space, the value column one space in and padded to its width. It answers None wherever its
layout could differ from rich's, and the caller then prints with rich: a terminal or any
variable that makes rich colour or resize (FORCE_COLOR, TTY_COMPATIBLE, a notebook), text that
is not printable ASCII (cell widths), a value with a word wider than its column (rich cuts it
short with an ellipsis), or a width that leaves the values narrower than the labels (rich
then shrinks both columns). tests/test_plaintext.py compares it with rich.
"""

from __future__ import annotations

import os
import re
import sys
from collections.abc import Sequence

__all__ = ["console_width", "render", "wrap"]

_WORD = re.compile(r"\s*\S+\s*")
_TRAILING_SPACE = re.compile(r"\s+$")
#: the environment variables that make rich colour, resize or detect a notebook
_RICH_ENVIRONMENT = ("FORCE_COLOR", "TTY_COMPATIBLE", "JUPYTER_COLUMNS", "JUPYTER_LINES")


def console_width() -> int | None:
    """The width rich's console would use for stdout, or None where it would colour, or where
    this module does not follow how it decides (Windows, a notebook)."""
    if sys.platform == "win32" or any(v in os.environ for v in _RICH_ENVIRONMENT):
        return None
    import builtins

    if hasattr(builtins, "get_ipython") or getattr(sys.stdin, "__module__", "").startswith("idlelib"):
        return None
    try:
        if sys.stdout.isatty():
            return None
    except (AttributeError, ValueError):
        pass  # a closed or replaced stdout: rich takes it for no terminal
    width = None
    for fd in (0, 1, 2):  # rich asks stdin, stdout, stderr in turn
        try:
            width = os.get_terminal_size(fd).columns
            break
        except (AttributeError, ValueError, OSError):
            pass
    columns = os.environ.get("COLUMNS")
    if columns is not None and columns.isdigit():
        width = int(columns)
    return width or 80


def wrap(text: str, width: int) -> list[str]:
    """`text` (one line) word-wrapped at `width` as rich wraps it: each word with the spaces after
    it, a line broken before a word that does not fit, a word longer than `width` folded."""
    breaks: list[int] = []
    offset = 0
    for match in _WORD.finditer(text):
        start, word = match.start(), match.group(0)
        length = len(word.rstrip())
        if width - offset >= length:
            offset += len(word)
        elif length > width:
            chunks = [word[i:i + width] for i in range(0, len(word), width)]
            for i, chunk in enumerate(chunks):
                if start:
                    breaks.append(start)
                if i == len(chunks) - 1:
                    offset = len(chunk)
                else:
                    start += len(chunk)
        elif offset and start:
            breaks.append(start)
            offset = len(word)
    bounds = [0, *breaks, len(text)]
    return [_crop_spaces(text[a:b], width)[:width] for a, b in zip(bounds, bounds[1:])]


def _crop_spaces(line: str, width: int) -> str:
    """Trailing spaces beyond `width` dropped (those within it are kept, as rich keeps them)."""
    excess = len(line) - width
    match = _TRAILING_SPACE.search(line)
    if excess <= 0 or match is None:
        return line
    return line[:len(line) - min(len(match.group(0)), excess)]


def render(headline: str, rows: Sequence[tuple[str, str]], width: int) -> str | None:
    """The headline wrapped at `width`, then a borderless table of (label, value) rows: what rich
    prints for `Text(headline)` and `Table(show_header=False, box=None, pad_edge=False)` piped.
    None where rich's layout could differ (see the module's docstring)."""
    texts = [headline, *(t for row in rows for t in row)]
    if not rows or not all(t.isascii() and t.isprintable() for t in texts):
        return None
    labels = max((len(label) for label, _ in rows), default=0) + 1
    values = max((len(value) for _, value in rows), default=0) + 1
    if labels + values > width and width < 2 * labels:
        return None
    values = min(values, width - labels)
    if any(len(word) > values - 1 for _, value in rows for word in value.split()):
        return None  # rich cuts such a word short with an ellipsis
    out = wrap(headline, width)
    for label, value in rows:
        for i, line in enumerate(wrap(value, values - 1)):
            out.append((label if i == 0 else "").ljust(labels) + " " + line.ljust(values - 1))
    return "\n".join(out) + "\n"
