"""Options shared by every command, set by the root callback and read through `ctx.obj`."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["CliState"]


@dataclass(frozen=True)
class CliState:
    """What the global options (`--db`) resolved to."""

    db_url: str | None = None
