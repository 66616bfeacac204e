"""The API-key look-up of one worker: its own database connection on its own thread, so a
key is checked while a check runs on the checker's thread, and the event loop never waits on
the database. One indexed SELECT of the token's SHA-256 per request (no cache: a revoked key
fails from its next request)."""

from __future__ import annotations

import asyncio
from concurrent.futures import ThreadPoolExecutor

from authn.service.auth import Caller, Forbidden, RolePolicy, Unauthenticated
from authn.service.keys import lookup

#: longer tokens are refused without a look-up (ours are 49 characters)
MAX_TOKEN_CHARS = 256


class KeyStore:
    def __init__(self, db_url: str | None, roles: RolePolicy) -> None:
        from registry.dbapi import Database

        self.roles = roles
        self.executor = ThreadPoolExecutor(1, "authn-keys")
        self.db = Database(db_url)
        self.executor.submit(self.db.connection).result()

    def _decide(self, token: str, action: str) -> Caller:
        found = lookup(self.db, token) if len(token) <= MAX_TOKEN_CHARS else None
        if found is None:
            raise Unauthenticated("unknown or revoked API key")
        who = Caller(*found)
        if not self.roles.allows(who, action):
            raise Forbidden(f"API key {who.key_id} (role {who.role}) may not {action.replace('_', ' ')}")
        return who

    async def caller(self, token: str, action: str) -> Caller:
        """The key's caller if its role may do `action`; else Unauthenticated or Forbidden."""
        return await asyncio.get_running_loop().run_in_executor(self.executor, self._decide, token, action)

    def close(self) -> None:
        self.executor.submit(self.db.close).result()
        self.executor.shutdown()
