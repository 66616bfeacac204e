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
