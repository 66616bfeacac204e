"""`authn db upgrade`: apply the Alembic migrations of the registry and audit schema."""

from __future__ import annotations

import typer


db_app = typer.Typer(help="Database schema management.", no_args_is_help=True)


@db_app.command("upgrade")
def upgrade_cmd(
    ctx: typer.Context,
    create: bool = typer.Option(False, "--create",
                                help="Create a new SQLite database, its directory too (other commands refuse "
                                     "a --db whose directory does not exist)."),
) -> None:
    """Apply all pending migrations (also done automatically on first use).

    Safe to run from several processes at once: migrations run under a lock.
    A new SQLite file in a directory that does not exist yet is made only with
    --create (so that a mistyped --db never becomes an empty registry); a new
    file is announced on stderr.

    Example: authn --db postgresql+psycopg://user@localhost/authn db upgrade

    Example: authn --db sqlite:////srv/authn/registry.sqlite3 db upgrade --create
    """
    from registry.db import create_db_engine, upgrade
    from registry.urls import announce_created, resolve_url, sqlite_file

    target = sqlite_file(resolve_url(ctx.obj.db_url))
    new_file = target is not None and not target.exists()
    engine = create_db_engine(ctx.obj.db_url, create=create)
    try:
        upgrade(engine)
        from alembic.runtime.migration import MigrationContext

        with engine.connect() as conn:
            rev = MigrationContext.configure(conn).get_current_revision()
    finally:
        engine.dispose()
    if new_file:
        announce_created(resolve_url(ctx.obj.db_url))
    typer.echo(f"database {engine.url.render_as_string()} at revision {rev}")
