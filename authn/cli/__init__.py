"""The `authn` command line: the root Typer app, its commands and command groups each defined
in one module (`COMMANDS`, `GROUPS`; nothing registers itself on import) and imported only when
that command runs or help lists it (`authn.cli.lazy`), and the commands of installed plugins
(`authn.cli.plugins`: the laboratory's `authn bench` and `authn features accuracy|score`),
loaded only when asked for.

Heavy libraries (scipy, sklearn, torch, matplotlib, sqlalchemy) are imported inside the
commands that need them, never at module level, so `authn --help` and a single
`authn check` start fast.
"""

from __future__ import annotations

import functools
import importlib
import os
import sys

# pydantic looks up plugins through importlib.metadata on its first model (~15 ms of a
# cold check); we use none. Set the variable yourself to re-enable them.
os.environ.setdefault("PYDANTIC_DISABLE_PLUGINS", "__all__")

import typer

from authn.cli.lazy import LazyGroup
from authn.cli.output import json_error, json_requested
from authn.cli.plugins import PluginGroup
from authn.cli.signals import handled, interrupted
from authn.cli.state import CliState
from authn.process import exit_quickly
from core.errors import AuthnException, Interrupted, describe, exit_code_for
from core.textsafe import printable

__all__ = ["app", "command", "main", "run"]
HELP_OPTIONS = ["-h", "--help"]
#: the widest an options table's type column may be in help
TYPE_COLUMN = 16

app = typer.Typer(
    name="authn",
    help="Radar micro-Doppler + Remote ID identity authentication for UAVs.\n\nExample: authn demo",
    no_args_is_help=True,
    cls=LazyGroup,  # commands imported when used (authn/cli/lazy.py), and installed plugins' (plugins.py)
    pretty_exceptions_enable=False,
    add_completion=True,  # --install-completion / --show-completion (bash, zsh, fish, PowerShell)
    context_settings={"help_option_names": HELP_OPTIONS},  # inherited by every subcommand
)


def _version(value: bool) -> None:
    if value:
        from importlib.metadata import PackageNotFoundError, version

        try:
            typer.echo(f"authn {version('uav-radar-authn')}")
        except PackageNotFoundError:
            typer.echo("authn (not installed as a package)")
        raise typer.Exit(0)


@app.callback()
def _global_options(
    ctx: typer.Context,
    db_url: str | None = typer.Option(
        None,
        "--db",
        help="SQLAlchemy database URL (default: $AUTHN_DATABASE_URL, else a SQLite file in the user data directory).",
    ),
    _show_version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                       help="Print the version and exit."),
) -> None:
    ctx.obj = CliState(db_url=db_url)


#: Each command: its name -> (module, function), in the order help lists them.
COMMANDS = {"check": ("authn.cli.check", "check"), "simulate": ("authn.cli.simulate", "simulate"),
            "inspect": ("authn.cli.inspect", "inspect_file"), "register": ("authn.cli.registry", "register_cmd"),
            "demo": ("authn.cli.demo", "demo"), "plot": ("authn.cli.plot", "plot"),
            "serve": ("authn.cli.serve", "serve")}
#: Each command group: its name -> (module, Typer app), listed after the commands.
GROUPS = {"registry": ("authn.cli.registry", "registry_app"), "audit": ("authn.cli.audit", "audit_app"),
          "rid": ("authn.cli.rid", "rid_app"), "db": ("authn.cli.db", "db_app"),
          "features": ("authn.cli.features", "features_app"), "models": ("authn.cli.models", "models_app"),
          "keys": ("authn.cli.keys", "keys_app"), "import": ("authn.cli.importer", "import_app")}
#: One example per command group (each command's own examples are in its docstring).
GROUP_EXAMPLES = {"registry": "authn registry list", "audit": "authn audit verify --json",
                  "rid": "authn rid decode --pcap odid_wifi_bcn_sample.pcap", "db": "authn db upgrade",
                  "features": "authn features show m300.h5", "models": "authn models list --json",
                  "keys": "authn keys generate --out ua.pem",
                  "import": "authn import dca1000 adc_data_Raw_0.bin --config profile.cfg"}


def _build(name: str):  # -> click Command
    """The click command `name` as a child of `app`: its module imported, registered on a
    parent built like `app` (so typer gives it the same settings), help styled as the rest."""
    module, attr = {**COMMANDS, **GROUPS}[name]
    obj = getattr(importlib.import_module(module), attr)
    parent = typer.Typer(pretty_exceptions_enable=False, add_completion=False,
                         context_settings={"help_option_names": HELP_OPTIONS})
    parent.callback()(lambda: None)
    if name in GROUPS:
        parent.add_typer(obj, name=name, help=f"{obj.info.help}\n\nExample: {GROUP_EXAMPLES[name]}")
    else:
        parent.command(name)(obj)
    cmd = typer.main.get_command(parent).commands[name]  # type: ignore[attr-defined]
    _plain_flags(cmd)
    _plugins_below(cmd, (name,))
    return cmd


def main(argv: list[str] | None = None) -> int:
    """Run the CLI and return the exit code (tests call this directly).

    Every exception ends here as one line on stderr: bad input exits 2, anything else
    (database, policy engine, models, an unexpected bug) exits 3. Never a traceback. A usage
    error (unknown option, value out of range) is bad input too: one line naming the command's
    help, not click's boxed usage text; a bare group (`authn registry`) still prints its help.
    With `--json` on the command line, that line is instead one JSON object on stdout,
    `{"error": "...", "exit_code": N}` (a `--json` reader never has to parse text).
    """
    import registry.urls

    args = _global_options_first(sys.argv[1:] if argv is None else list(argv))
    as_json = _json_mode(args)
    previous, registry.urls.created_notice = registry.urls.created_notice, _announce_created
    try:
        with handled(_raise_interrupted):
            code = command()(args=args, prog_name="authn", standalone_mode=False)
        return code if isinstance(code, int) else 0
    except SystemExit as exc:
        code = exc.code
        return code if isinstance(code, int) else (0 if code is None else 1)
    except typer.Abort:
        return _fail("aborted", 130, as_json, prefix="error: ")
    except Interrupted as exc:  # a BaseException: no handler below swallowed it
        return _fail(describe(exc), exc.exit_code, as_json, prefix="error: ")
    except Exception as exc:  # noqa: BLE001 - the one place every error becomes an exit code
        if _is_usage_error(exc):
            return _usage_error(exc, as_json)
        return _fail(describe(exc), exit_code_for(exc), as_json,
                     prefix="error: " if isinstance(exc, AuthnException) else "")
    finally:
        registry.urls.created_notice = previous


@functools.cache
def command():  # -> click Command
    """The click command tree of `app` (built once per process), with on/off flags shown in
    help without a `<bool>` type: a flag takes no value, and help tables that wrap prose only
    (installed when help is first rendered: a check never imports rich's help machinery); each
    command and group built when first asked for (`_build`)."""
    cmd = typer.main.get_command(app)
    _plain_flags(cmd)
    _plugins_below(cmd)
    cmd.lazy = {name: functools.partial(_build, name) for name in (*COMMANDS, *GROUPS)}
    return cmd


def _plugins_below(cmd, path: tuple[str, ...] = ()) -> None:
    """Each plugin-aware group told its command path and the help styling its plugins get."""
    if isinstance(cmd, PluginGroup):
        cmd.path, cmd.prepare = path, _plain_flags
    for name, sub in getattr(cmd, "commands", {}).items():
        _plugins_below(sub, (*path, name))


def _help_tables_wrap_prose_only() -> None:
    """Help at 80 columns: typer's option and command tables let rich squeeze every column, so a
    long option name (`--max-connections-per-client`) came out cut (`--max-connections-per…`).
    The option-name columns are made no-wrap: only the type and the help text wrap. The type
    column of an options table is held to `TYPE_COLUMN` characters (`INTEGER RANGE [1<=x<=64]`
    folds onto two lines): unbounded, it takes the help text's width and leaves it a ragged strip."""
    import typer.rich_utils as ru
    from rich.table import Table

    if getattr(ru.Table, "_authn_prose_only", False):
        return

    class HelpTable(Table):
        _authn_prose_only = True

        def add_row(self, *renderables, **kwargs):  # type: ignore[no-untyped-def]
            super().add_row(*renderables, **kwargs)
            for column in self.columns[:-2]:  # the option names (the type and help columns wrap)
                column.no_wrap = True
            if len(self.columns) >= 4:  # an options table (a commands table has name and help)
                self.columns[-2].max_width = TYPE_COLUMN

    ru.Table = HelpTable


def _plain_flags(cmd) -> None:
    """Flags without a type, help text reflowed (`authn.cli.helptext`), help tables that wrap
    prose only: on `cmd` and every command below it."""
    from authn.cli.helptext import reflow

    cmd.help = reflow(cmd.help)
    help_option = cmd.get_help_option(cmd.context_class(cmd, info_name=cmd.name, help_option_names=HELP_OPTIONS))
    for param in [*cmd.params, *([help_option] if help_option is not None else [])]:  # help: built once, cached
        if getattr(param, "is_flag", False) and param.metavar is None:
            param.metavar = ""
    render = cmd.format_help

    def format_help(ctx, formatter):  # type: ignore[no-untyped-def]
        _help_tables_wrap_prose_only()
        return render(ctx, formatter)

    cmd.format_help = format_help
    for sub in getattr(cmd, "commands", {}).values():
        _plain_flags(sub)


def _json_mode(args: list[str]) -> bool:
    """Errors as JSON: `--json` given to a command whose `--json` is a switch (`models evaluate
    --json FILE` writes a report file: its errors stay text). `check` keeps its own contract:
    per-file errors inside its JSON output, a fatal error (exit 3) on stderr only, stdout
    holding only what was decided and audited (docs/policies.md)."""
    rest = list(args)
    while rest and rest[0].startswith("--db"):  # `_global_options_first` put them in front
        rest = rest[1:] if "=" in rest[0] else rest[2:]
    words = [a for a in rest if not a.startswith("-")][:2]
    return json_requested(args) and words != ["models", "evaluate"] and words[:1] != ["check"]


def _fail(message: str, code: int, as_json: bool, prefix: str = "error: ") -> int:
    """The error: one line on stderr, or one JSON object on stdout with --json."""
    if as_json:
        json_error(printable(message), code)
    else:
        print(prefix + message, file=sys.stderr)
    return code


def _announce_created(url: str) -> None:
    """One line on stderr when a command created a new (empty) SQLite database."""
    print(printable(f"authn: created new database {url} (empty registry)"), file=sys.stderr)


def _is_usage_error(exc: Exception) -> bool:
    """click's ClickException family, whichever click raised it: typer >= 0.2x vendors its own
    copy (`typer._click`, private), older ones use click's. Duck-typed on click's interface."""
    return isinstance(getattr(exc, "exit_code", None), int) and callable(getattr(exc, "format_message", None))


def _usage_error(exc: Exception, as_json: bool = False) -> int:
    """One line on stderr naming the command's help; a bare group's help as click prints it."""
    if type(exc).__name__ == "NoArgsIsHelpError":
        exc.show()  # type: ignore[attr-defined]
        return int(exc.exit_code)  # type: ignore[attr-defined]
    ctx = getattr(exc, "ctx", None)
    where = f" (see '{ctx.command_path} --help')" if ctx is not None else ""
    message = printable(" ".join(exc.format_message().split()))  # type: ignore[attr-defined]
    return _fail(f"{message}{where}", int(exc.exit_code), as_json)  # type: ignore[attr-defined]


def _global_options_first(argv: list[str]) -> list[str]:
    """`--db URL` is accepted after the subcommand too (`authn check f.h5 --db URL`): moved to
    the front, where the root callback reads it. No subcommand has an option of that name."""
    out, front, i = [], [], 0
    while i < len(argv):
        arg = argv[i]
        if arg == "--":
            out.extend(argv[i:])
            break
        if arg == "--db" and i + 1 < len(argv):
            front += argv[i:i + 2]
            i += 2
            continue
        if arg.startswith("--db="):
            front.append(arg)
        else:
            out.append(arg)
        i += 1
    return front + out


def _raise_interrupted(signum: int, _frame: object) -> None:
    raise interrupted(signum)


def run() -> None:
    """The command as a process (`authn.__main__`, the console script, which has tuned it before
    importing this module: `authn.process.tune`), then an exit that skips the collector's last
    full pass (`authn.process.exit_quickly`)."""
    code = main()
    exit_quickly()
    sys.exit(code)
