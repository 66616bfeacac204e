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


def _info(row: Any) -> ApiKeyInfo:
    return ApiKeyInfo(row.id, row.name, row.role, row.created_at, row.revoked_at)


def create_key(db_url: str | None, role: str, name: str | None = None) -> tuple[ApiKeyInfo, str]:
    """A new key: its record and the token (returned once, never stored)."""
    from core.errors import AuthnError
    from registry.db import session_scope
    from registry.models import ApiKey, utcnow

    if role not in ROLES:
        raise AuthnError(f"--role: must be operator or admin, got {role!r}")
    if name is not None and not 1 <= len(name) <= 100:
        raise AuthnError("--name: 1 to 100 characters")
    token = TOKEN_PREFIX + secrets.token_urlsafe(32)
    with session_scope(db_url) as s:
        row = ApiKey(name=name, role=role, key_hash=token_hash(token), created_at=utcnow())
        s.add(row)
        s.flush()
        return _info(row), token


def list_keys(db_url: str | None) -> list[ApiKeyInfo]:
    from sqlalchemy import select

    from registry.db import session_scope
    from registry.models import ApiKey

    with session_scope(db_url) as s:
        return [_info(r) for r in s.scalars(select(ApiKey).order_by(ApiKey.id))]


def revoke_key(db_url: str | None, key_id: int) -> ApiKeyInfo:
    from core.errors import AuthnError
    from registry.db import session_scope
    from registry.models import ApiKey, utcnow

    with session_scope(db_url) as s:
        row = s.get(ApiKey, key_id)
        if row is None:
            raise AuthnError(f"no API key {key_id}")
        if row.revoked_at is not None:
            raise AuthnError(f"API key {key_id}: already revoked")
        row.revoked_at = utcnow()
        s.flush()
        return _info(row)


def lookup(db: Any, token: str) -> tuple[int, str] | None:
    """(id, role) of an active key with this token, through the check path's DB-API connection."""
    rows = db.fetch("SELECT id, role FROM api_keys WHERE key_hash = :h AND revoked_at IS NULL",
                    {"h": token_hash(token)})
    return (int(rows[0][0]), str(rows[0][1])) if rows else None
