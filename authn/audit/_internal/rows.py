"""Audit rows as stored: the columns read, the one stored form of a time, and a row's leaf
bytes, checked against the columns that copy them (authn.audit.leaf)."""

from __future__ import annotations

import re
from collections.abc import Iterator, Sequence
from datetime import datetime, timezone
from typing import Any

from authn.audit import leaf
from registry.dbapi import Database

COLUMNS = "seq, created_at, kind, serial, decision, payload, prev_hash, entry_hash, leaf_hash, leaf_bytes"

PAGE = 5000

_TEXT_COLUMNS = ("kind", "serial", "decision", "payload", "prev_hash", "entry_hash", "leaf_hash")
_OPTIONAL = ("serial", "decision", "leaf_hash")

#: created_at as the writer stores it in SQLite (Database.to_db_time, UTC): the only text accepted
_SQLITE_CANONICAL = re.compile(r"\d{4}-\d{2}-\d{2} \d{2}:\d{2}:\d{2}\.\d{6}")


class MalformedRow(ValueError):
    """A stored audit row that the writer could not have written: a column of the wrong type,
    a time not in the one stored form, leaf bytes missing or in no known encoding."""


class ColumnsAltered(MalformedRow):
    """A row whose readable columns say something other than its leaf bytes: one of them was
    changed after the writer wrote both."""


def utc_text(value: object) -> str:
    """created_at from the stored value as "YYYY-MM-DDTHH:MM:SS.ffffff" (UTC): SQLite's text
    exactly as the writer stores it, or PostgreSQL's timestamptz (an instant). Any other
    representation, the same instant in another UTC offset included, raises MalformedRow."""
    if isinstance(value, str) and _SQLITE_CANONICAL.fullmatch(value):
        return f"{value[:10]}T{value[11:]}"
    if isinstance(value, datetime) and value.tzinfo is not None and value.utcoffset() is not None:
        return value.astimezone(timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%f")
    shown = value if isinstance(value, str) else type(value).__name__
    raise MalformedRow(f"created_at {shown!r} is not a UTC time in the form the writer stores")


def stored_leaf(row: Sequence[Any]) -> bytes:
    """The leaf bytes of a stored row (a row of COLUMNS), after checking that its columns are
    what the writer stores and say what the bytes say; MalformedRow otherwise."""
    seq, created, kind, serial, decision, payload, prev_hash, entry_hash, leaf_hash, body = row
    if type(seq) is not int:
        raise MalformedRow("seq is not an integer")
    for name, value in zip(_TEXT_COLUMNS, (kind, serial, decision, payload, prev_hash, entry_hash, leaf_hash)):
        if value.__class__ is not str and not (value is None and name in _OPTIONAL):
            raise MalformedRow(f"{name} is {type(value).__name__}, not text")
    if isinstance(body, memoryview):
        body = body.tobytes()
    if not isinstance(body, bytes):
        raise MalformedRow("leaf_bytes is missing" if body is None else f"leaf_bytes is {type(body).__name__}")
    when = utc_text(created)
    v = leaf.version(body)
    if v == 1:
        expected = leaf.encode(seq, when + "Z", kind, serial, decision, payload, prev_hash)
    elif v == 0:
        expected = leaf.encode_v0(seq, when + "+00:00", kind, serial, decision, payload, prev_hash)
    else:
        raise MalformedRow("leaf_bytes is in no known encoding")
    if expected != body:
        raise ColumnsAltered("its columns disagree with its leaf bytes")
    return body


def rows(db: Database) -> Iterator[tuple]:
    """Raw rows in seq order, a page at a time (keyset pagination)."""
    last = None
    while True:
        page = db.fetch(f"SELECT {COLUMNS} FROM audit_log" + ("" if last is None else " WHERE seq > :last")
                        + f" ORDER BY seq, id LIMIT {PAGE}", {} if last is None else {"last": last})
        yield from page
        if len(page) < PAGE:
            return
        last = page[-1][0]
