"""The one runtime data-access layer: DB-API on the driver itself, no SQLAlchemy (~0.23 s).

`authn check` runs once per process, so start-up is its latency; every query of the product
(the check's identity row, the registry store, API keys, the audit log) runs here on stdlib
`sqlite3` for SQLite files and `psycopg` for PostgreSQL, against the schema Alembic created,
with named `:param` placeholders on both. A database that is not at the current revision is
handed to `registry.db.migrate`, which migrates it under its lock: SQLAlchemy and Alembic are
imported for that and nothing else. A database found current is not asked its version again by
the same process.
"""

from __future__ import annotations

import re
import sqlite3
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import datetime, timezone
from typing import Any
from urllib.parse import parse_qsl, unquote, urlsplit

from signatures.profiles import UavProfile
from registry.errors import DatabaseFault, RegistryError
from registry.urls import announce_created, check_backend, prepare_sqlite, resolve_url

#: Seconds a writer waits for another's lock before the check fails as a system error (exit 3).
LOCK_TIMEOUT_S = 30.0
_NAMED = re.compile(r"(?<!:):([A-Za-z_]\w*)")


@dataclass(frozen=True)
class IdentityFacts:
    """What a decision needs from an identity row."""

    serial: str
    id_type: str
    model: str
    status: str
    valid_from: datetime
    valid_until: datetime | None
    public_key: bytes | None = None  # raw Ed25519 host identity (DRIP), when registered with one


def utcnow() -> datetime:
    """Now, timezone-aware in UTC (what every stored time is)."""
    return datetime.now(timezone.utc)


def _first_line(exc: BaseException) -> str:
    lines = str(exc).strip().splitlines()
    return lines[0] if lines else type(exc).__name__


def _sqlite_path(url: str) -> str:
    rest = url.split(":///", 1)[1] if ":///" in url else ""
    if rest in ("", ":memory:"):
        raise RegistryError("an in-memory SQLite database cannot be shared with `authn check`; use a file")
    return rest.split("?", 1)[0]


def _pg_kwargs(url: str) -> dict[str, Any]:
    parts = urlsplit(url)
    kw: dict[str, Any] = {k: v for k, v in parse_qsl(parts.query)}
    if parts.hostname:
        kw["host"] = parts.hostname
    if parts.port:
        kw["port"] = parts.port
    if parts.username:
        kw["user"] = unquote(parts.username)
    if parts.password:
        kw["password"] = unquote(parts.password)
    if parts.path.strip("/"):
        kw["dbname"] = unquote(parts.path.strip("/"))
    return kw


#: URLs whose schema this process found at the newest revision: migrations only go forward, so
#: a connection to one of them skips the version query (a round trip on PostgreSQL)
_CURRENT: set[str] = set()


class Database:
    """One driver connection, reused for every check of a process (batch mode)."""

    def __init__(self, url: str | None = None) -> None:
        self.url = resolve_url(url)
        self.dialect = check_backend(self.url)
        self._conn: Any = None
        self._new_file = False  # this process created the SQLite file: announced once it opened

    # --- connection -------------------------------------------------------------------
    def _open(self) -> Any:
        if self.dialect == "sqlite":
            path = _sqlite_path(self.url)
            self._new_file = prepare_sqlite(self.url) or self._new_file  # a missing directory: bad input
            try:
                conn = sqlite3.connect(path, timeout=LOCK_TIMEOUT_S, isolation_level=None)
                conn.execute("PRAGMA foreign_keys = ON")
            except (sqlite3.Error, OSError) as exc:
                raise DatabaseFault(f"cannot open database {path}: {_first_line(exc)}") from None
            return conn
        try:
            import psycopg
        except ImportError as exc:  # pragma: no cover - psycopg is a dependency
            raise DatabaseFault(f"PostgreSQL needs psycopg: {exc}") from None
        try:
            return psycopg.connect(**{"connect_timeout": 10, **_pg_kwargs(self.url)}, autocommit=True)
        except psycopg.Error as exc:
            raise DatabaseFault(f"cannot open database: {_first_line(exc)}") from None

    def _driver_errors(self) -> tuple[type[BaseException], ...]:
        if self.dialect == "sqlite":
            return (sqlite3.Error,)
        import psycopg

        return (psycopg.Error,)

    @contextmanager
    def _faults(self, what: str) -> Iterator[None]:
        """Driver errors (locked, read-only, lost connection) become one-line system faults."""
        try:
            yield
        except self._driver_errors() as exc:
            raise DatabaseFault(f"database {what} failed: {_first_line(exc)}") from None

    def _current(self, conn: Any) -> bool:
        from registry import migrations

        try:
            rows = self._fetch(conn, migrations.VERSION_QUERY, {})
        except self._driver_errors():  # no version table yet: a fresh database (autocommit: no aborted txn)
            rows = None
        return migrations.is_current(rows)

    def connection(self) -> Any:
        """The open connection, after making sure the schema is current (migrating once if not).
        A database this process has found current is not asked again (`_CURRENT`), unless this
        process has just created its file."""
        if self._conn is None:
            conn = self._open()
            if (self.url not in _CURRENT or self._new_file) and not self._current(conn):
                conn.close()
                from registry.db import migrate

                migrate(self.url)  # under the file lock / advisory lock
                conn = self._open()
            self._conn = conn
            _CURRENT.add(self.url)
            if self._new_file:
                self._new_file = False
                announce_created(self.url)
        return self._conn

    def close(self) -> None:
        if self._conn is not None:
            self._conn.close()
            self._conn = None

    # --- statements -------------------------------------------------------------------
    def _sql(self, sql: str) -> str:
        return sql if self.dialect == "sqlite" else _NAMED.sub(r"%(\1)s", sql)

    def _fetch(self, conn: Any, sql: str, params: dict[str, Any]) -> list[tuple]:
        cur = conn.cursor()
        try:
            cur.execute(self._sql(sql), params)
            return list(cur.fetchall())
        finally:
            cur.close()

    def fetch(self, sql: str, params: dict[str, Any] | None = None) -> list[tuple]:
        """Rows of one query (named `:param` placeholders on both backends)."""
        conn = self.connection()
        with self._faults("read"):
            return self._fetch(conn, sql, params or {})

    @contextmanager
    def write(self) -> Iterator["Database"]:
        """One write transaction (SQLite: BEGIN IMMEDIATE, so writers queue instead of failing).

        Driver errors inside it (a lock held past LOCK_TIMEOUT_S, a read-only file, a lost
        server) roll back and surface as DatabaseFault; nothing of the transaction is kept."""
        conn = self.connection()
        if self.dialect == "sqlite":
            with self._faults("write"):
                conn.execute("BEGIN IMMEDIATE")
            try:
                with self._faults("write"):
                    yield self
                    conn.execute("COMMIT")
            except BaseException:
                if conn.in_transaction:
                    conn.execute("ROLLBACK")
                raise
            return
        with self._faults("write"), conn.transaction():
            yield self

    def execute(self, sql: str, params: dict[str, Any] | None = None, *, what: str | None = None) -> None:
        """One statement inside `write()`; with `what`, a constraint the row violates is bad
        input naming it (RegistryError `what: already registered` for a unique key), else a
        DatabaseFault like any driver error."""
        cur = self.connection().cursor()
        try:
            with self._faults("write"), self._refusals(what):
                cur.execute(self._sql(sql), params or {})
        finally:
            cur.close()

    def execute_many(self, sql: str, rows: list[dict[str, Any]], *, what: str | None = None) -> None:
        """One data-changing statement per parameter set (a bulk insert), errors as `execute`."""
        if not rows:
            return
        cur = self.connection().cursor()
        try:
            with self._faults("write"), self._refusals(what):
                cur.executemany(self._sql(sql), rows)
        finally:
            cur.close()

    def _integrity_errors(self) -> tuple[type[BaseException], ...]:
        if self.dialect == "sqlite":
            return (sqlite3.IntegrityError,)
        import psycopg

        return (psycopg.IntegrityError,)

    @contextmanager
    def _refusals(self, what: str | None) -> Iterator[None]:
        if what is None:
            yield
            return
        try:
            yield
        except self._integrity_errors() as exc:
            msg = _first_line(exc)
            if "unique" in msg.lower() or "duplicate" in msg.lower():
                raise RegistryError(f"{what}: already registered") from None
            raise RegistryError(f"{what}: rejected by the database ({msg})") from None

    # --- values -----------------------------------------------------------------------
    def to_db_time(self, when: datetime) -> Any:
        try:
            when = when.astimezone(timezone.utc)
        except OverflowError:  # 0001-01-01T00:00:00+23:59: before year 1 in UTC
            raise RegistryError(f"time {when.isoformat()} is out of range in UTC") from None
        # SQLite: naive UTC text, `YYYY-MM-DD HH:MM:SS.ffffff` (four-digit years: ordered as text)
        return when.replace(tzinfo=None).isoformat(" ", "microseconds") if self.dialect == "sqlite" else when

    @staticmethod
    def from_db_time(value: Any) -> datetime | None:
        if value is None:
            return None
        if isinstance(value, str):
            value = datetime.fromisoformat(value)
        return value.replace(tzinfo=timezone.utc) if value.tzinfo is None else value.astimezone(timezone.utc)

    # --- the check's registry reads ------------------------------------------------
    def identity(self, serial: str) -> IdentityFacts | None:
        rows = self.fetch("SELECT serial, id_type, model_slug, status, valid_from, valid_until, public_key "
                          "FROM identities WHERE serial = :serial", {"serial": serial})
        if not rows:
            return None
        s, id_type, model, status, vf, vu, key = rows[0]
        valid_from = self.from_db_time(vf)
        if valid_from is None:  # NOT NULL in the schema: a row that breaks it decides nothing
            raise DatabaseFault(f"identity {s!r}: its row has no valid_from")
        return IdentityFacts(s, id_type, model, status, valid_from, self.from_db_time(vu),
                             bytes(key) if key is not None else None)

    def registered_models(self) -> set[str]:
        """The model slugs of the active identities: the airframes registered at this site (what
        a radar-confusable pair is checked against, `authn.check`)."""
        return {str(r[0]) for r in self.fetch("SELECT model_slug FROM identities WHERE status = :s GROUP BY model_slug",
                                              {"s": "active"})}

    def registered_profiles(self) -> list[UavProfile]:
        """The profiles of the models of the active identities, in one query: the alternatives a
        claim is verified against (`signatures.classify.verify`, `authn.check`)."""
        rows = self.fetch("SELECT slug, name, rotors, arms, blades_per_rotor, blade_length_m, rotor_rate_hz, "
                          "propeller_distance_m FROM model_profiles WHERE slug IN "
                          "(SELECT model_slug FROM identities WHERE status = :s) ORDER BY slug", {"s": "active"})
        return [UavProfile(slug=slug, name=name, rotors=rotors, arms=arms, blades_per_rotor=blades,
                           blade_length_m=length, rotor_rate_hz=rate, propeller_distance_m=dist)
                for slug, name, rotors, arms, blades, length, rate, dist in rows]

    def profile(self, slug: str) -> UavProfile | None:
        """The registered model's physical parameters (what 1:1 verification checks against);
        read only when the radar runs, so a registry-only rejection costs one query."""
        rows = self.fetch("SELECT name, rotors, arms, blades_per_rotor, blade_length_m, rotor_rate_hz, "
                          "propeller_distance_m FROM model_profiles WHERE slug = :slug", {"slug": slug})
        if not rows:
            return None
        name, rotors, arms, blades, length, rate, dist = rows[0]
        return UavProfile(slug=slug, name=name, rotors=rotors, arms=arms, blades_per_rotor=blades,
                          blade_length_m=length, rotor_rate_hz=rate, propeller_distance_m=dist)


@contextmanager
def transaction(url: str | None = None) -> Iterator[Database]:
    """One write transaction on a connection of its own (a registry command, a service request):
    committed when the block ends, rolled back with nothing kept on any exception."""
    db = Database(url)
    try:
        with db.write():
            yield db
    finally:
        db.close()
