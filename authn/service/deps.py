"""FastAPI dependencies: the worker's runtime, and the caller allowed to do an action."""

from __future__ import annotations

from collections.abc import Awaitable, Callable

from fastapi import Request, Security
from fastapi.security import APIKeyHeader, HTTPAuthorizationCredentials, HTTPBearer

from authn.service.auth import Caller, Unauthenticated
from authn.service.gate import ACTION_ATTR, CALLER
from authn.service.runtime import Runtime

# declared for the OpenAPI schema (/docs "Authorize"); the token itself is read by token_of
_bearer = HTTPBearer(auto_error=False)
_api_key = APIKeyHeader(name="X-API-Key", auto_error=False)


def runtime(request: Request) -> Runtime:
    return request.app.state.runtime


def require(action: str) -> Callable[..., Awaitable[Caller]]:
    """A dependency that needs a caller whose key's role the service policy allows `action`.

    `gate.Authenticate` checks the key before the body is read (it finds `action` on this
    dependency) and leaves the caller in the request's state; without it, no caller."""

    async def caller(request: Request, _b: HTTPAuthorizationCredentials | None = Security(_bearer),
                     _k: str | None = Security(_api_key)) -> Caller:
        who = getattr(request.state, CALLER, None)
        if not isinstance(who, Caller):
            raise Unauthenticated("no authenticated caller")
        return who

    setattr(caller, ACTION_ATTR, action)
    return caller
