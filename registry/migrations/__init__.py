"""Alembic migration environment for the registry and audit schema."""

#: The newest revision in versions/. Lets a process confirm its database is current
#: with one SELECT instead of importing Alembic (~0.2 s); a test keeps it equal to
#: Alembic's own head.
HEAD_REVISION = "0008"

#: The one query both database paths (SQLAlchemy in registry.db, DB-API in registry.dbapi)
#: run to ask which revision a database is at.
VERSION_QUERY = "SELECT version_num FROM alembic_version"


def is_current(version_rows: list[tuple] | None) -> bool:
    """Whether a database whose `VERSION_QUERY` returned these rows is at HEAD_REVISION
    (None: it has no version table yet, a fresh database)."""
    return version_rows is not None and [r[0] for r in version_rows] == [HEAD_REVISION]
