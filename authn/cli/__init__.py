"""The `authn` command line: one Typer app, one module per command group.

Heavy libraries (scipy, sklearn, torch, matplotlib, sqlalchemy) are imported
inside the commands that need them, never here, so `authn --help` and a
single `authn check` start fast.
"""

from __future__ import annotations

import os
import sys

# pydantic looks up plugins through importlib.metadata on its first model (~15 ms of a
# cold check); we use none. Set the variable yourself to re-enable them.
os.environ.setdefault("PYDANTIC_DISABLE_PLUGINS", "__all__")
from dataclasses import dataclass

import typer

from authn.errors import bad_input_types

app = typer.Typer(
    name="authn",
    help="Radar micro-Doppler + Remote ID identity authentication for UAVs.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)


@dataclass(frozen=True)
class CliState:
    """Options shared by every command (set by the top-level callback)."""

    db_url: str | None = None


@app.callback()
def _global_options(
    ctx: typer.Context,
    db: str | None = typer.Option(
        None,
        "--db",
        envvar="AUTHN_DATABASE_URL",
        help="SQLAlchemy database URL (default: SQLite file in the user data directory).",
    ),
) -> None:
    ctx.obj = CliState(db_url=db)


def main(argv: list[str] | None = None) -> int:
    """Run the CLI and return the exit code (tests call this directly)."""
    try:
        app(args=argv, prog_name="authn")
    except SystemExit as exc:
        code = exc.code
        return code if isinstance(code, int) else (0 if code is None else 1)
    except bad_input_types() as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


def run() -> None:
    """Console-script entry point."""
    sys.exit(main())


from authn.cli import inspect_cmd as _inspect_cmd  # noqa: E402,F401  (registers commands)
from authn.cli import simulate as _simulate  # noqa: E402,F401
from authn.cli import registry_cmds as _registry_cmds  # noqa: E402,F401
from authn.cli import rid as _rid  # noqa: E402,F401
from authn.cli import db as _db  # noqa: E402,F401
from authn.cli import audit_cmds as _audit_cmds  # noqa: E402,F401
from authn.cli import check_cmd as _check_cmd  # noqa: E402,F401
from authn.cli import demo_cmd as _demo_cmd  # noqa: E402,F401
from authn.cli import models as _models  # noqa: E402,F401
from authn.cli import bench_cmd as _bench_cmd  # noqa: E402,F401
from authn.cli import features as _features  # noqa: E402,F401
from authn.cli import plot as _plot  # noqa: E402,F401
