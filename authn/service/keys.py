"""API keys: a random 32-byte token shown once, stored as its SHA-256 (a token this long
needs no slow hash: it cannot be guessed from the hash), with a role and a revocation time."""

from __future__ import annotations

import hashlib
import secrets
from dataclasses import dataclass
from datetime import datetime
from typing import Any

ROLES = ("operator", "admin")
TOKEN_PREFIX = "authn_"


def token_hash(token: str) -> str:
    return hashlib.sha256(token.encode("utf-8")).hexdigest()


@dataclass(frozen=True)
class ApiKeyInfo:
    id: int
    name: str | None
    role: str
    created_at: datetime
    revoked_at: datetime | None

    def to_json(self) -> dict[str, Any]:
        return {"id": self.id, "name": self.name, "role": self.role, "created_at": self.created_at.isoformat(),
                "revoked_at": self.revoked_at.isoformat() if self.revoked_at else None}


_COLUMNS = "id, name, role, created_at, revoked_at"


def _info(row: tuple) -> ApiKeyInfo:
    from registry.dbapi import Database

    created_at, revoked_at = (Database.from_db_time(t) for t in row[3:5])
    return ApiKeyInfo(int(row[0]), row[1], str(row[2]), created_at, revoked_at)  # type: ignore[arg-type]


def create_key(db_url: str | None, role: str, name: str | None = None) -> tuple[ApiKeyInfo, str]:
    """A new key: its record and the token (returned once, never stored)."""
    from core.errors import AuthnError
    from registry.dbapi import transaction, utcnow

    if role not in ROLES:
        raise AuthnError(f"--role: must be operator or admin, got {role!r}")
    if name is not None and not 1 <= len(name) <= 100:
        raise AuthnError("--name: 1 to 100 characters")
    token = TOKEN_PREFIX + secrets.token_urlsafe(32)
    with transaction(db_url) as db:
        params = {"name": name, "role": role, "h": token_hash(token), "at": db.to_db_time(utcnow())}
        db.execute("INSERT INTO api_keys (name, role, key_hash, created_at) VALUES (:name, :role, :h, :at)", params)
        return _info(db.fetch(f"SELECT {_COLUMNS} FROM api_keys WHERE key_hash = :h", {"h": params["h"]})[0]), token


def list_keys(db_url: str | None) -> list[ApiKeyInfo]:
    from registry.dbapi import transaction

    with transaction(db_url) as db:
        return [_info(r) for r in db.fetch(f"SELECT {_COLUMNS} FROM api_keys ORDER BY id")]


def revoke_key(db_url: str | None, key_id: int) -> ApiKeyInfo:
    from core.errors import AuthnError
    from registry.dbapi import transaction, utcnow

    with transaction(db_url) as db:
        rows = db.fetch(f"SELECT {_COLUMNS} FROM api_keys WHERE id = :id", {"id": key_id})
        if not rows:
            raise AuthnError(f"no API key {key_id}")
        if rows[0][4] is not None:
            raise AuthnError(f"API key {key_id}: already revoked")
        db.execute("UPDATE api_keys SET revoked_at = :at WHERE id = :id",
                   {"at": db.to_db_time(utcnow()), "id": key_id})
        return _info(db.fetch(f"SELECT {_COLUMNS} FROM api_keys WHERE id = :id", {"id": key_id})[0])


def lookup(db: Any, token: str) -> tuple[int, str] | None:
    """(id, role) of an active key with this token, through the check path's DB-API connection."""
    rows = db.fetch("SELECT id, role FROM api_keys WHERE key_hash = :h AND revoked_at IS NULL",
                    {"h": token_hash(token)})
    return (int(rows[0][0]), str(rows[0][1])) if rows else None
