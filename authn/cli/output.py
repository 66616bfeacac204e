"""Output that survives pipes and narrow terminals, and the JSON error object.

- `print_table`: a rich table on a terminal; piped (stdout not a terminal), one plain line per
  row, cells separated by tabs, no title, caption or header (like `gh`): `cut -f1` works.
  Identifier columns are built with `no_wrap=True` (never split), prose columns wrap.
- `json_requested` / `json_error`: with `--json` anywhere on the command line, an error is one
  JSON object on stdout (`{"error": "...", "exit_code": N}`), never text (docs/architecture.md).
"""

from __future__ import annotations

import json
import sys
from typing import Any

__all__ = ["DECISION_COLOURS", "is_terminal", "json_error", "json_requested", "plain_cell", "print_table",
           "to_decide_line"]

#: How a decision is coloured on a terminal: inconclusive is no accept, and no refutation either.
DECISION_COLOURS = {"accept": "green", "inconclusive": "yellow", "reject": "red"}


def is_terminal() -> bool:
    """stdout is a terminal (a table), not a pipe or file (tab-separated lines)."""
    try:
        return sys.stdout.isatty()
    except (AttributeError, ValueError):  # a closed or replaced stdout
        return False


def plain_cell(value: Any) -> str:
    """A table cell as plain text: rich markup rendered away, tabs and line breaks as spaces."""
    from rich.text import Text

    if isinstance(value, Text):
        text = value.plain
    else:
        try:
            text = Text.from_markup(str(value)).plain
        except Exception:  # noqa: BLE001 - not markup after all: the text as given
            text = str(value)
    return " ".join(text.replace("\t", " ").splitlines())


def print_table(table: Any, console: Any = None) -> None:
    """A rich Table on a terminal, tab-separated lines (one per row) otherwise."""
    if is_terminal():
        from rich.console import Console

        (console or Console()).print(table)
        return
    columns = list(table.columns)
    for i in range(table.row_count):
        print("\t".join(plain_cell(c._cells[i]) if i < len(c._cells) else "" for c in columns))


def json_requested(argv: list[str]) -> bool:
    """`--json` was given (before any `--`): errors are then printed as one JSON object."""
    for arg in argv:
        if arg == "--":
            return False
        if arg == "--json" or arg.startswith("--json="):
            return True
    return False


def json_error(message: str, exit_code: int) -> None:
    """The one JSON error object, on stdout (where a `--json` reader looks)."""
    print(json.dumps({"error": message, "exit_code": exit_code}))


def to_decide_line(d: dict) -> str:
    """An inconclusive decision's `to_decide` (`Evidence.to_decide`) in words."""
    if not d["dwells"]:
        return "nothing verified the claim: a dwell whose rotors the radar reads, or a valid DRIP signature"
    parts = [f"LLR {d['llr_nats']:+.2f} nats after {d['dwells']} dwell(s), against {d['closest']} "
             f"(accept >= {d['accept_nats']:.2f}, refute <= {d['reject_nats']:.2f})"]
    if d["more_dwells"] is not None:
        parts.append(f"about {d['more_dwells']} more dwell(s) would decide it "
                     f"({d['separation_nats_per_dwell']:+.2f} nats per dwell, from {d['separation_from']})")
    else:
        parts.append("more dwells would not decide it (the radar cannot separate the claim from "
                     f"{d['closest']})")
    if d["signature"]:
        parts.append("a valid DRIP signature would")
    return "; ".join(parts)
