"""Alembic's engine: schema migrations applied on first use (queries run in registry.dbapi).

Alembic works through a SQLAlchemy engine, so this module holds one per URL (a SQLite file
or PostgreSQL, `registry.urls`) for migrating and nothing else: the first use of a database
upgrades it to the newest revision under a lock (a file lock beside a SQLite file, a
`pg_advisory_lock` on PostgreSQL) so that processes starting together do not race. SQLite
engines run in WAL mode (which the file keeps) with foreign keys on, a busy timeout and
`BEGIN IMMEDIATE` transactions. Imported only to migrate (`registry.dbapi` hands a database
that is not current here), never by a check of a current database.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any

from sqlalchemy import Connection, Engine, create_engine, event, text
from sqlalchemy.engine import make_url
from sqlalchemy.exc import ArgumentError, DBAPIError

from registry.errors import DatabaseFault, RegistryError
from registry.urls import announce_created, check_backend, prepare_sqlite, resolve_url, sqlite_file

if TYPE_CHECKING:
    from alembic.config import Config

_PG_LOCK_KEY = 0x61757468_6E726567  # "authnreg": one advisory lock for migrations
_engines: dict[str, Engine] = {}
_engines_lock = threading.Lock()


def _sqlite_setup(engine: Engine) -> None:
    @event.listens_for(engine, "connect")
    def _on_connect(dbapi_conn: Any, _record: Any) -> None:
        dbapi_conn.isolation_level = None  # we issue BEGIN ourselves
        cur = dbapi_conn.cursor()
        cur.execute("PRAGMA busy_timeout = 30000")
        cur.execute("PRAGMA foreign_keys = ON")
        if engine.url.database not in (None, "", ":memory:"):
            _set_wal(cur)
        cur.close()

    @event.listens_for(engine, "begin")
    def _on_begin(conn: Connection) -> None:
        conn.exec_driver_sql("BEGIN IMMEDIATE")


#: Switching a new file to WAL takes an exclusive lock that SQLite's busy handler does not wait
#: for: processes opening the same new database at once retry it this often, this far apart.
_WAL_TRIES = 100
_WAL_WAIT_S = 0.05


def _set_wal(cur: Any) -> None:
    """PRAGMA journal_mode = WAL, retried while another connection holds the lock it needs."""
    import sqlite3
    import time

    for attempt in range(_WAL_TRIES):
        try:
            cur.execute("PRAGMA journal_mode = WAL")
            return
        except sqlite3.OperationalError as exc:
            if "locked" not in str(exc) or attempt == _WAL_TRIES - 1:
                raise
            time.sleep(_WAL_WAIT_S)


def create_db_engine(url: str | None = None, *, create: bool = False) -> Engine:
    """A new engine for `url` (see resolve_url); no migration is run. Only sqlite and
    postgresql URLs; a SQLite file's directory must exist unless it is the default database
    or `create` (see registry.urls.prepare_sqlite)."""
    resolved = resolve_url(url)
    check_backend(resolved)
    try:
        parsed = make_url(resolved)
    except ArgumentError:
        raise RegistryError(f"database URL {resolved!r} is not a valid SQLAlchemy URL") from None
    prepare_sqlite(resolved, create=create)
    try:
        engine = create_engine(parsed, pool_pre_ping=parsed.get_backend_name() != "sqlite")
    except (ArgumentError, ImportError) as exc:
        raise RegistryError(f"database URL {parsed.render_as_string()!r}: {exc}") from None
    if engine.dialect.name == "sqlite":
        _sqlite_setup(engine)
    return engine


def alembic_config(connection: Connection | None = None) -> Config:
    """Alembic Config built in code: works from an installed package, no alembic.ini."""
    from alembic.config import Config

    from registry import migrations

    cfg = Config()
    cfg.set_main_option("script_location", str(Path(migrations.__file__).parent))
    cfg.attributes["connection"] = connection
    return cfg


def _is_current(conn: Connection) -> bool:
    """One SELECT against `alembic_version` (Alembic itself is imported only to upgrade)."""
    from sqlalchemy import inspect

    from registry import migrations

    if not inspect(conn).has_table("alembic_version"):  # a failed SELECT would abort a PostgreSQL transaction
        return migrations.is_current(None)
    return migrations.is_current(list(conn.execute(text(migrations.VERSION_QUERY)).all()))


def _upgrade_on(conn: Connection) -> None:
    from alembic import command

    command.upgrade(alembic_config(conn), "head")


def upgrade(engine: Engine) -> None:
    """Apply all pending migrations, serialised against other processes."""
    try:
        if engine.dialect.name == "postgresql":
            with engine.connect() as conn:
                conn.execute(text("SELECT pg_advisory_lock(:k)"), {"k": _PG_LOCK_KEY})
                conn.commit()
                try:
                    if not _is_current(conn):
                        _upgrade_on(conn)
                    conn.commit()
                finally:
                    conn.rollback()
                    conn.execute(text("SELECT pg_advisory_unlock(:k)"), {"k": _PG_LOCK_KEY})
                    conn.commit()
            return
        db = engine.url.database if engine.dialect.name == "sqlite" else None
        if db and db != ":memory:":
            from filelock import FileLock

            with FileLock(str(Path(db).expanduser()) + ".migrate.lock", timeout=120):
                _upgrade_locked(engine)
        else:
            _upgrade_locked(engine)
    except DBAPIError as exc:
        raise DatabaseFault(f"database {engine.url.render_as_string()}: {_one_line(exc)}") from None
    except TimeoutError as exc:  # filelock.Timeout: another process holds the migration lock
        raise DatabaseFault(f"database {engine.url.render_as_string()}: migration lock busy ({exc})") from None


def _upgrade_locked(engine: Engine) -> None:
    with engine.begin() as conn:
        if not _is_current(conn):
            _upgrade_on(conn)


def _one_line(exc: DBAPIError) -> str:
    return str(exc.orig).strip().splitlines()[0] if exc.orig else str(exc).splitlines()[0]


def get_engine(url: str | None = None) -> Engine:
    """The process-wide engine for `url`, migrated to the newest schema on first use."""
    resolved = resolve_url(url)
    with _engines_lock:
        engine = _engines.get(resolved)
        if engine is None:
            target = sqlite_file(resolved)
            new_file = target is not None and not target.exists()
            engine = create_db_engine(resolved)
            _migrate(engine)
            _engines[resolved] = engine
            if new_file:
                announce_created(resolved)
    return engine


def migrate(url: str) -> None:
    """Bring the database at `url` to the newest schema now, even if this process migrated it
    before (its SQLite file may have been replaced since): what `registry.dbapi` calls when it
    finds a database behind."""
    resolved = resolve_url(url)
    with _engines_lock:
        cached = resolved in _engines
    engine = get_engine(resolved)  # a new engine is migrated as it is made
    if cached:
        with _engines_lock:
            engine.dispose()  # pooled connections may hold a file since replaced
            _migrate(engine)


def _migrate(engine: Engine) -> None:
    try:
        with engine.connect() as conn:
            current = _is_current(conn)
    except DBAPIError as exc:
        raise DatabaseFault(f"cannot open database {engine.url.render_as_string()}: {_one_line(exc)}") from None
    if not current:
        upgrade(engine)


def dispose_engines() -> None:
    """Close every cached engine (tests, forked workers)."""
    with _engines_lock:
        for engine in _engines.values():
            engine.dispose()
        _engines.clear()
