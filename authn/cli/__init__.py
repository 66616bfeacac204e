"""The `authn` command line: one Typer app, one module per command group.

Heavy libraries (scipy, sklearn, torch, matplotlib, sqlalchemy) are imported
inside the commands that need them, never here, so `authn --help` and a
single `authn check` start fast.
"""

from __future__ import annotations

import os
import signal
import sys
from collections.abc import Iterator
from contextlib import contextmanager

# pydantic looks up plugins through importlib.metadata on its first model (~15 ms of a
# cold check); we use none. Set the variable yourself to re-enable them.
os.environ.setdefault("PYDANTIC_DISABLE_PLUGINS", "__all__")
from dataclasses import dataclass

import typer

from authn.errors import AuthnException, Interrupted, exit_code_for, one_line

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
    """Run the CLI and return the exit code (tests call this directly).

    Every exception ends here as one line on stderr: bad input exits 2, anything else
    (database, policy engine, models, an unexpected bug) exits 3. Never a traceback.
    """
    try:
        with _signals_as_errors():
            app(args=argv, prog_name="authn")
    except SystemExit as exc:
        code = exc.code
        return code if isinstance(code, int) else (0 if code is None else 1)
    except Exception as exc:  # noqa: BLE001 - the one place every error becomes an exit code
        prefix = "error" if isinstance(exc, AuthnException) else "internal error"
        print(f"{prefix}: {_describe(exc)}", file=sys.stderr)
        return exit_code_for(exc)
    return 0


@contextmanager
def _signals_as_errors() -> Iterator[None]:
    """SIGINT/SIGTERM raise `Interrupted` (exit 3, one line) instead of click's "Aborted!" with
    exit 1, which would read as a reject. Only the main thread can install handlers."""
    def handler(signum: int, _frame: object) -> None:
        raise Interrupted(f"interrupted by {signal.Signals(signum).name}")

    previous = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        try:
            previous[sig] = signal.signal(sig, handler)
        except ValueError:
            break
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def _describe(exc: BaseException) -> str:
    """One line; SQLAlchemy wraps driver errors with the SQL and a link: keep the driver's message."""
    orig = getattr(exc, "orig", None)
    if orig is not None:
        return f"database: {one_line(orig)}"
    text = one_line(exc)
    return text if isinstance(exc, AuthnException) else f"{type(exc).__name__}: {text}"


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
