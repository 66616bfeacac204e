"""The CLI reference (docs/cli*.md), generated from the typer app: every command with its help
and a table of its options, so the reference cannot drift from the code.

`python -m authn.cli.reference docs` writes the pages; tests/test_cli_reference.py regenerates
them and fails when the committed ones differ. Markdown only, no terminal rendering: the output
does not depend on the terminal's width or the machine. Pages stay under `MAX_LINES` (the docs
limit): the commands run on over as many pages as needed, `cli.md` first with the index.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path

__all__ = ["MAX_LINES", "pages", "write"]

#: the most lines a generated page holds (docs pages stay under 300)
MAX_LINES = 280


def _commands(cmd, path: tuple[str, ...] = ()) -> Iterator[tuple[tuple[str, ...], object]]:
    """(path, click command) of every visible command below `cmd`, in name order."""
    for name, sub in sorted(getattr(cmd, "commands", {}).items()):
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
        subs = [f"[{n}](#{_anchor(' '.join(('authn', *path, n)))})" for n, c in sorted(cmd.commands.items())
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
    """{file name: markdown} of the reference: `cli.md` (the index, then commands) and as many
    `cli-N.md` as the commands need to keep each page within `MAX_LINES`."""
    from authn.cli import command

    root = command()
    sections = [(path, _section(path, cmd)) for path, cmd in _commands(root)]
    head = ["# Command-line reference", "",
            "Generated from the `authn` command itself (`python -m authn.cli.reference docs`; a test fails",
            "when these pages are not current). Every command also answers `-h`.", ""]
    page_of: dict[tuple[str, ...], str] = {}
    bodies: list[list[str]] = [[]]
    budget = MAX_LINES - len(head) - len(sections) - 4  # the index table on the first page
    for path, lines in sections:
        if len(bodies[-1]) + len(lines) > budget:
            bodies.append([])
            budget = MAX_LINES - 4
        bodies[-1] += lines
        page_of[path] = "cli.md" if len(bodies) == 1 else f"cli-{len(bodies)}.md"
    index = ["| command | what it does |", "|---|---|"]
    for path, cmd in _commands(root):
        name = " ".join(("authn", *path))
        summary = _cell((cmd.help or "").split("\n\n")[0])
        index.append(f"| [{name}]({'' if page_of[path] == 'cli.md' else page_of[path]}#{_anchor(name)}) "
                     f"| {summary} |")
    out = {"cli.md": "\n".join(head + index + [""] + bodies[0]).rstrip() + "\n"}
    for i, body in enumerate(bodies[1:], 2):
        top = [f"# Command-line reference ({i} of {len(bodies)})", "", "Index: [cli.md](cli.md).", ""]
        out[f"cli-{i}.md"] = "\n".join(top + body).rstrip() + "\n"
    return out


def write(folder: Path) -> list[Path]:
    """Write the reference pages into `folder` (and remove continuation pages it no longer
    needs); returns their paths."""
    folder.mkdir(parents=True, exist_ok=True)
    new = pages()
    for old in folder.glob("cli-*.md"):
        if old.name not in new:
            old.unlink()
    written = []
    for name, text in new.items():
        (folder / name).write_text(text)
        written.append(folder / name)
    return written


if __name__ == "__main__":
    for p in write(Path(sys.argv[1] if len(sys.argv) > 1 else "docs")):
        print(p)
