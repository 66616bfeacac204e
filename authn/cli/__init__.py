"""The `authn` command line: the root Typer app, composed here from one module per command
or command group (the modules define their commands and sub-apps; nothing registers itself
on import).

Heavy libraries (scipy, sklearn, torch, matplotlib, sqlalchemy) are imported inside the
commands that need them, never at module level, so `authn --help` and a single
`authn check` start fast.
"""

from __future__ import annotations

import os
import sys

# pydantic looks up plugins through importlib.metadata on its first model (~15 ms of a
# cold check); we use none. Set the variable yourself to re-enable them.
os.environ.setdefault("PYDANTIC_DISABLE_PLUGINS", "__all__")

import typer

from authn.cli import (audit, bench, check, db, demo, features, importer, inspect, keys, models, plot, registry, rid,
                       serve, simulate)
from authn.cli.signals import handled, interrupted
from authn.cli.state import CliState
from core.errors import AuthnException, describe, exit_code_for
from core.textsafe import printable

__all__ = ["app", "main", "run"]

app = typer.Typer(
    name="authn",
    help="Radar micro-Doppler + Remote ID identity authentication for UAVs.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
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
        envvar="AUTHN_DATABASE_URL",
        help="SQLAlchemy database URL (default: SQLite file in the user data directory).",
    ),
    _show_version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                       help="Print the version and exit."),
) -> None:
    ctx.obj = CliState(db_url=db_url)


for _name, _command in (("check", check.check), ("simulate", simulate.simulate), ("inspect", inspect.inspect_file),
                        ("register", registry.register_cmd), ("demo", demo.demo), ("plot", plot.plot),
                        ("bench", bench.bench), ("serve", serve.serve)):
    app.command(_name)(_command)
for _name, _group in (("registry", registry.registry_app), ("audit", audit.audit_app), ("rid", rid.rid_app),
                      ("db", db.db_app), ("features", features.features_app), ("models", models.models_app),
                      ("keys", keys.keys_app), ("import", importer.import_app)):
    app.add_typer(_group, name=_name)


def main(argv: list[str] | None = None) -> int:
    """Run the CLI and return the exit code (tests call this directly).

    Every exception ends here as one line on stderr: bad input exits 2, anything else
    (database, policy engine, models, an unexpected bug) exits 3. Never a traceback. A usage
    error (unknown option, value out of range) is bad input too: one line naming the command's
    help, not click's boxed usage text; a bare group (`authn registry`) still prints its help.
    """
    import registry.urls

    previous, registry.urls.created_notice = registry.urls.created_notice, _announce_created
    try:
        with handled(_raise_interrupted):
            code = app(args=_global_options_first(sys.argv[1:] if argv is None else list(argv)), prog_name="authn",
                       standalone_mode=False)
        return code if isinstance(code, int) else 0
    except SystemExit as exc:
        code = exc.code
        return code if isinstance(code, int) else (0 if code is None else 1)
    except typer.Abort:
        print("error: aborted", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - the one place every error becomes an exit code
        if _is_usage_error(exc):
            return _usage_error(exc)
        print(("error: " if isinstance(exc, AuthnException) else "") + describe(exc), file=sys.stderr)
        return exit_code_for(exc)
    finally:
        registry.urls.created_notice = previous


def _announce_created(url: str) -> None:
    """One line on stderr when a command created a new (empty) SQLite database."""
    print(printable(f"authn: created new database {url} (empty registry)"), file=sys.stderr)


def _is_usage_error(exc: Exception) -> bool:
    """click's ClickException family, whichever click raised it: typer >= 0.2x vendors its own
    copy (`typer._click`, private), older ones use click's. Duck-typed on click's interface."""
    return isinstance(getattr(exc, "exit_code", None), int) and callable(getattr(exc, "format_message", None))


def _usage_error(exc: Exception) -> int:
    """One line on stderr naming the command's help; a bare group's help as click prints it."""
    if type(exc).__name__ == "NoArgsIsHelpError":
        exc.show()  # type: ignore[attr-defined]
        return int(exc.exit_code)  # type: ignore[attr-defined]
    ctx = getattr(exc, "ctx", None)
    where = f" (see '{ctx.command_path} --help')" if ctx is not None else ""
    message = printable(" ".join(exc.format_message().split()))  # type: ignore[attr-defined]
    print(f"error: {message}{where}", file=sys.stderr)
    return int(exc.exit_code)  # type: ignore[attr-defined]


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
    """Console-script entry point."""
    sys.exit(main())
