"""`authn db upgrade`: apply the Alembic migrations of the registry and audit schema."""

from __future__ import annotations

import typer


db_app = typer.Typer(help="Database schema management.", no_args_is_help=True)


@db_app.command("upgrade")
def upgrade_cmd(ctx: typer.Context) -> None:
    """Apply all pending migrations (also done automatically on first use).

    Safe to run from several processes at once: migrations run under a lock.

    Example: authn --db postgresql+psycopg://user@localhost/authn db upgrade
    """
    from registry.db import create_db_engine, upgrade

    engine = create_db_engine(ctx.obj.db_url)
    try:
        upgrade(engine)
        from alembic.runtime.migration import MigrationContext

        with engine.connect() as conn:
            rev = MigrationContext.configure(conn).get_current_revision()
    finally:
        engine.dispose()
    typer.echo(f"database {engine.url.render_as_string()} at revision {rev}")
