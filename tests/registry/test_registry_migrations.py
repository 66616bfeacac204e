"""Migrations: ORM and migrated schema agree; first use migrates once, even under a race."""

from __future__ import annotations

from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import inspect, text

from registry.migrations import HEAD_REVISION
from registry.db import create_db_engine, get_engine, upgrade
from registry.models import Base


def test_models_match_migrated_schema(db_url):
    engine = get_engine(db_url)
    with engine.connect() as conn:
        ctx = MigrationContext.configure(conn, opts={"compare_type": True,
                                                     "compare_server_default": True})
        assert compare_metadata(ctx, Base.metadata) == []


def test_upgrade_is_idempotent_and_creates_everything(db_url):
    engine = create_db_engine(db_url)
    upgrade(engine)
    upgrade(engine)
    tables = set(inspect(engine).get_table_names())
    assert {"model_profiles", "identities", "audit_log", "alembic_version"} <= tables
    engine.dispose()


def test_concurrent_first_use_migrates_once(db_url):
    from registry_workers import first_use, run_in_processes

    assert run_in_processes(first_use, [(db_url,)] * 4) == [HEAD_REVISION] * 4
    with get_engine(db_url).connect() as conn:
        assert conn.execute(text("SELECT count(*) FROM model_profiles")).scalar_one() == 3
        assert conn.execute(text("SELECT count(*) FROM alembic_version")).scalar_one() == 1


def test_head_revision_constant_matches_alembic() -> None:
    """`migrations.HEAD_REVISION` (read without importing Alembic) is Alembic's head."""
    from alembic.script import ScriptDirectory

    from registry import migrations
    from registry.db import alembic_config

    assert ScriptDirectory.from_config(alembic_config()).get_heads() == [migrations.HEAD_REVISION]


def _schema(engine) -> tuple[set[str], set[str]]:
    """(tables, append-only triggers) as the database reports them."""
    tables = set(inspect(engine).get_table_names())
    query = ("SELECT name FROM sqlite_master WHERE type = 'trigger'" if engine.dialect.name == "sqlite"
             else "SELECT tgname FROM pg_trigger WHERE NOT tgisinternal")
    with engine.connect() as conn:
        return tables, {r[0] for r in conn.execute(text(query))}


def test_downgrade_to_base_and_back_restores_the_schema(db_url) -> None:
    """Every revision's downgrade undoes its upgrade: down to nothing, then up again, gives the
    same tables and append-only triggers (PostgreSQL: trigger functions dropped with them, or
    the second upgrade's CREATE FUNCTION would fail)."""
    from alembic import command

    from registry.db import alembic_config

    engine = create_db_engine(db_url)
    upgrade(engine)
    head = _schema(engine)
    assert {"audit_log_no_update", "audit_log_no_delete", "audit_batches_no_update",
            "audit_log_meta_no_delete"} <= head[1]
    with engine.begin() as conn:
        command.downgrade(alembic_config(conn), "base")
    tables, triggers = _schema(engine)
    assert tables <= {"alembic_version"} and not triggers
    upgrade(engine)
    assert _schema(engine) == head
    engine.dispose()
