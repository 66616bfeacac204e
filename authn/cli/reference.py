"""The CLI reference (docs/cli.md and docs/cli/*.md), generated from the typer app: every
command with its help and a table of its options, so the reference cannot drift from the code.

`python -m authn.cli.reference docs` writes the pages; tests/test_cli_reference.py regenerates
them and fails when the committed ones differ. Markdown only, no terminal rendering: the output
does not depend on the terminal's width or the machine. One page per top-level command keeps
each under the docs' 300 lines (`MAX_LINES`, checked by the test).
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path

__all__ = ["MAX_LINES", "pages", "subcommands", "write"]

#: the most lines a generated page holds (docs pages stay under 300)
MAX_LINES = 280


def subcommands(cmd, path: tuple[str, ...] = ()) -> dict[str, object]:
    """{name: click command} directly below `cmd` (the command at `path`), as the group lists
    them: those of installed plugins too (`authn.cli.plugins`), loaded to be listed."""
    import click

    if not isinstance(cmd, click.Group):
        return {}
    ctx = click.Context(cmd, info_name=" ".join(("authn", *path)))
    return {name: cmd.get_command(ctx, name) for name in cmd.list_commands(ctx)}


def _commands(cmd, path: tuple[str, ...] = ()) -> Iterator[tuple[tuple[str, ...], object]]:
    """(path, click command) of every visible command below `cmd`, in name order."""
    for name, sub in sorted(subcommands(cmd, path).items()):
        if getattr(sub, "hidden", False):
            continue
        yield (*path, name), sub
        yield from _commands(sub, (*path, name))


def _cell(text: str) -> str:
    """Text for one markdown table cell: one line, pipes escaped."""
    return " ".join(str(text).split()).replace("|", "\\|")


def _option_row(param) -> str:
    """One option as a table row: names and value type, default, help."""
    import click

    names = ", ".join(f"`{o}`" for o in [*param.opts, *param.secondary_opts])
    kind = "" if getattr(param, "is_flag", False) else _cell(param.type.name.upper())
    if isinstance(param.type, click.types._NumberRangeBase):
        kind += f" {_cell(param.type._describe_range())}"
    default = param.default
    shown = "" if default in (None, False, (), []) or callable(default) or param.show_default is False else \
        f"`{_cell(', '.join(map(str, default)) if isinstance(default, (list, tuple)) else default)}`"
    return f"| {names} | {kind.strip()} | {shown} | {_cell(param.help or '')} |"


def _section(path: tuple[str, ...], cmd) -> list[str]:
    """A command's section: heading, usage, help paragraphs, arguments and options."""
    import click

    from authn.cli.helptext import reflow

    name = " ".join(("authn", *path))
    args = " ".join(p.human_readable_name.upper() + ("..." if p.nargs == -1 else "")
                    for p in cmd.params if isinstance(p, click.Argument))
    sub = " COMMAND" if hasattr(cmd, "commands") else ""
    lines = [f"## {name}", "", f"`{name}{sub}{' [OPTIONS]' if _options(cmd) else ''}{' ' + args if args else ''}`",
             ""]
    for paragraph in (reflow(cmd.help or "") or "").split("\n\n"):
        lines += [" ".join(paragraph.replace("\b", "").split()), ""]
    if hasattr(cmd, "commands"):
        subs = [f"[{n}](#{_anchor(' '.join(('authn', *path, n)))})" for n, c in sorted(subcommands(cmd, path).items())
                if not getattr(c, "hidden", False)]
        lines += ["Commands: " + ", ".join(subs) + ".", ""]
    options = _options(cmd)
    if options:
        lines += ["| option | value | default | what it does |", "|---|---|---|---|"]
        lines += [_option_row(p) for p in options] + [""]
    return lines


def _options(cmd) -> list:
    import click

    return [p for p in cmd.params if isinstance(p, click.Option) and not p.hidden]


def _anchor(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, spaces as '-', punctuation dropped."""
    return "".join(c for c in heading.lower().replace(" ", "-") if c.isalnum() or c in "-_")


def pages() -> dict[str, str]:
    """{path under docs/: markdown} of the reference: `cli.md`, the index of every command, and
    `cli/<command>.md`, one page per top-level command with its subcommands."""
    from authn.cli import command

    root = command()
    groups: dict[str, list[str]] = {}
    for path, cmd in _commands(root):
        groups.setdefault(path[0], []).extend(_section(path, cmd))
    index = ["# Command-line reference", "",
             "Generated from the `authn` command itself (`python -m authn.cli.reference docs`; a test fails",
             "when these pages are not current). Every command also answers `-h`.", "",
             "| command | what it does |", "|---|---|"]
    for path, cmd in _commands(root):
        name = " ".join(("authn", *path))
        summary = _cell((cmd.help or "").split("\n\n")[0])
        index.append(f"| [{name}](cli/{path[0]}.md#{_anchor(name)}) | {summary} |")
    out = {"cli.md": "\n".join(index).rstrip() + "\n"}
    for top, body in groups.items():
        head = [f"# authn {top}", "", "Part of the [command-line reference](../cli.md), generated from the command.",
                ""]
        out[f"cli/{top}.md"] = "\n".join(head + body).rstrip() + "\n"
    return out


def write(folder: Path) -> list[Path]:
    """Write the reference pages under `folder` (docs/), removing command pages of commands that
    no longer exist; returns their paths."""
    new = pages()
    (folder / "cli").mkdir(parents=True, exist_ok=True)
    for old in (folder / "cli").glob("*.md"):
        if f"cli/{old.name}" not in new:
            old.unlink()
    written = []
    for name, text in new.items():
        (folder / name).write_text(text)
        written.append(folder / name)
    return written


if __name__ == "__main__":
    for p in write(Path(sys.argv[1] if len(sys.argv) > 1 else "docs")):
        print(p)
