"""Commands that other distributions add to `authn`, through the entry-point group
`authn.plugins` (as pytest and datasette load theirs).

An entry point's name is the command's path, dotted (`bench`, `features.accuracy`): a new
top-level command, or a new command in one of the product's groups. Its value is a
function typer turns into a command (its options declared as typer's). Nothing is
looked up until a group is asked for a name it does not define or lists its commands for
help, so a cold `authn check` neither scans the installed distributions nor imports a
plugin. The product imports no plugin: it only knows which commands the laboratory
(`authn-lab`) provides, to say how to install it when one of them is asked for.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any

from typer.core import TyperGroup

from core.errors import BadInput, SystemFault

if TYPE_CHECKING:
    import click
    from importlib.metadata import EntryPoint

__all__ = ["ENTRY_POINT_GROUP", "LAB_COMMANDS", "PluginGroup", "by_path", "installed"]

#: the entry-point group a distribution registers its commands under
ENTRY_POINT_GROUP = "authn.plugins"
#: the commands the laboratory provides, named when it is not installed
LAB_COMMANDS = frozenset({("bench",), ("features", "accuracy"), ("features", "score")})
#: how to install the laboratory (it is not on PyPI: it ships in the repository)
LAB_INSTALL = "from a clone of the repository, pip install -e ./lab"


def by_path(entry_points: Iterable[EntryPoint]) -> dict[tuple[str, ...], EntryPoint]:
    """Each entry point by its command path (the name split on dots); the first one
    registered for a path wins, as Python's import path order decides."""
    out: dict[tuple[str, ...], EntryPoint] = {}
    for ep in entry_points:
        path = tuple(ep.name.split("."))
        if all(path) and path not in out:
            out[path] = ep
    return out


@functools.cache
def installed() -> dict[tuple[str, ...], EntryPoint]:
    """The plugin commands of the installed distributions (scanned once per process)."""
    from importlib.metadata import entry_points

    return by_path(entry_points(group=ENTRY_POINT_GROUP))


def as_command(name: str, obj: Any) -> click.Command:
    """A loaded entry point (a function) as a click command named `name`."""
    import typer

    if not callable(obj):
        raise SystemFault(f"plugin command {name!r} is a {type(obj).__name__}, not a function")
    single = typer.Typer(add_completion=False)  # completion belongs to `authn` itself
    single.command(name)(obj)
    return typer.main.get_command(single)


class PluginGroup(TyperGroup):
    """A typer group whose commands include the plugins registered below its `path`.

    `path` is the group's own command path (() for `authn`); `prepare` is applied to every
    plugin command once loaded (the product's help styling)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.path: tuple[str, ...] = ()
        self.prepare: Callable[[click.Command], None] | None = None

    def _here(self) -> dict[str, EntryPoint]:
        depth = len(self.path) + 1
        return {p[-1]: ep for p, ep in installed().items() if len(p) == depth and p[:-1] == self.path}

    def list_commands(self, ctx: click.Context) -> list[str]:
        own = super().list_commands(ctx)
        return own + sorted(n for n in self._here() if n not in own)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        own = super().get_command(ctx, cmd_name)
        if own is not None:
            return own
        ep = self._here().get(cmd_name)
        if ep is None:
            if (*self.path, cmd_name) in LAB_COMMANDS:
                raise BadInput(f"`authn {' '.join((*self.path, cmd_name))}` is in the laboratory (authn-lab), "
                               f"which is not installed: {LAB_INSTALL}")
            return None
        try:
            loaded = ep.load()
        except Exception as exc:  # any failure to import a plugin is the plugin's: named, exit 3
            where = f" ({ep.dist.name} {ep.dist.version})" if getattr(ep, "dist", None) else ""
            raise SystemFault(f"plugin command {ep.name!r}{where} failed to load: {type(exc).__name__}: {exc}") \
                from exc
        cmd = as_command(cmd_name, loaded)
        if self.prepare is not None:
            self.prepare(cmd)
        self.add_command(cmd, cmd_name)
        return cmd
