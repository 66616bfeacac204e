"""Untrusted text made safe for a terminal: control characters escaped, never written raw.

Serials, file names, import notes, Remote ID free text and error messages come from outside
(a broadcast, an uploaded file, a registry export) and reach the operator's terminal in the
human output. A raw ESC there is a terminal escape sequence (colours, cursor moves, window
titles, OSC 8 links); a bidi override reorders what the operator reads. `printable` writes
every such character as a visible escape instead: C0 controls (tab and newline included),
DEL and C1 controls as `\\x1b`, the bidi embeddings, overrides, isolates and marks as
`\\u202e`. Everything else (accents, CJK, emoji) is kept. A backslash is kept as it is, so a
literal `\\x1b` in the input reads the same as an escaped ESC: the escaping is for safety,
not a reversible encoding (JSON output, which escapes control characters itself, is the
exact form).

A leaf module: the standard library only (rich is imported by `cell`, when called).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rich.text import Text

__all__ = ["printable", "cell", "UNSAFE"]

#: Code points written as escapes: C0, DEL, C1, and the bidi controls (ALM, LRM/RLM,
#: LRE/RLE/PDF/LRO/RLO, LRI/RLI/FSI/PDI).
UNSAFE: frozenset[int] = frozenset(
    [*range(0x00, 0x20), 0x7F, *range(0x80, 0xA0), 0x061C, 0x200E, 0x200F, *range(0x202A, 0x202F),
     *range(0x2066, 0x206A)])
_TABLE = {c: (f"\\x{c:02x}" if c < 0x100 else f"\\u{c:04x}") for c in UNSAFE}


def printable(value: Any) -> str:
    """`str(value)` with every control or bidi character written as `\\xNN` / `\\uNNNN`."""
    text = value if isinstance(value, str) else str(value)
    return text.translate(_TABLE)


def cell(value: Any) -> Text:
    """A rich table cell (or console line) holding `value` as plain text: escaped by
    `printable`, and never read as rich markup (`[red]` in a serial stays text)."""
    from rich.text import Text

    return Text("" if value is None else printable(value))
