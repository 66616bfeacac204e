"""The root group's own commands, each imported only when it runs or help lists it.

A cold `authn check` should not import `simulate`, `serve` or `models` to run one check: the
root group knows every product command by name and the function that builds it
(`LazyGroup.lazy`), lists them in that order ahead of any plugin's, and builds one (imports its
module) the first time click asks for it by name: to run it, to complete it, or to list it in
help with its help text.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from authn.cli.plugins import PluginGroup

if TYPE_CHECKING:
    import click

__all__ = ["LazyGroup"]


class LazyGroup(PluginGroup):
    """A plugin-aware group whose own commands are built on first use.

    `lazy` maps each command name to a function returning its click command (in the order help
    lists them); a built command is kept, so each is built at most once per process."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.lazy: dict[str, Callable[[], click.Command]] = {}

    def list_commands(self, ctx: click.Context) -> list[str]:
        return [*self.lazy, *(n for n in super().list_commands(ctx) if n not in self.lazy)]

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name in self.lazy and cmd_name not in self.commands:
            self.add_command(self.lazy[cmd_name](), cmd_name)
        return super().get_command(ctx, cmd_name)
