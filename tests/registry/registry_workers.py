"""Functions run in spawned processes by the concurrency tests (must be importable)."""

from __future__ import annotations

from proc_workers import run_in_processes  # noqa: F401  (re-exported for the tests)


def register_many(url: str, serials: list[str], barrier) -> tuple[int, int]:
    """Register each serial; returns (registered, refused as duplicates)."""
    from registry.dbapi import transaction
    from registry.errors import RegistryError
    from registry.store import NewIdentity, register_identity

    barrier.wait()
    ok = dup = 0
    for s in serials:
        try:
            with transaction(url) as session:
                register_identity(session, NewIdentity(serial=s, model="m300", operator_id="OP-1"))
            ok += 1
        except RegistryError as exc:
            assert "already registered" in str(exc), str(exc)
            dup += 1
    return ok, dup


def first_use(url: str, barrier) -> str:
    """Open the database the way every command does (auto-migration on first use)."""
    from sqlalchemy import text

    from registry.db import get_engine

    barrier.wait()
    with get_engine(url).connect() as conn:
        return conn.execute(text("SELECT version_num FROM alembic_version")).scalar_one()
