"""Command groups below a group (`authn audit witness`, `authn keys api`): one way to make them."""

from __future__ import annotations

import typer


def subgroup(parent: typer.Typer, name: str, help: str, example: str) -> typer.Typer:
    """A group `name` under `parent`, its help ending in an example; bare, it prints its help."""
    group = typer.Typer(help=f"{help}\n\nExample: {example}", no_args_is_help=True)
    parent.add_typer(group, name=name)
    return group
