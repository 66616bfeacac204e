"""FastAPI dependencies: the worker's runtime, and the caller allowed to do an action."""

from __future__ import annotations

from collections.abc import Awaitable, Callable

from fastapi import Request
from fastapi.security import APIKeyHeader, HTTPAuthorizationCredentials, HTTPBearer
from fastapi import Security

from authn.service.auth import Caller, Forbidden, Unauthenticated, token_of
from authn.service.keys import lookup
from authn.service.runtime import Runtime

# declared for the OpenAPI schema (/docs "Authorize"); the token itself is read by token_of
_bearer = HTTPBearer(auto_error=False)
_api_key = APIKeyHeader(name="X-API-Key", auto_error=False)


def runtime(request: Request) -> Runtime:
    return request.app.state.runtime


def require(action: str) -> Callable[..., Awaitable[Caller]]:
    """A dependency that admits a caller whose key's role the service policy allows `action`."""

    async def caller(request: Request, _b: HTTPAuthorizationCredentials | None = Security(_bearer),
                     _k: str | None = Security(_api_key)) -> Caller:
        token = token_of(request.headers)
        if token is None:
            raise Unauthenticated("missing API key: send 'Authorization: Bearer <key>' or 'X-API-Key: <key>'")
        rt = runtime(request)
        found = await rt.run(lambda: lookup(rt.checker.db, token))
        if found is None:
            raise Unauthenticated("unknown or revoked API key")
        who = Caller(*found)
        if not rt.roles.allows(who, action):
            raise Forbidden(f"API key {who.key_id} (role {who.role}) may not {action.replace('_', ' ')}")
        return who

    return caller
