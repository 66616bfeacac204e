"""Authentication before the body: a pure ASGI layer that matches the request to its route,
checks the API key in the headers against the key store and the role policy, and answers
401/403 without ever calling `receive()`, so a client without a valid key cannot make the
server read (or spool, or parse) a byte of its body.

Which action a route needs is read from its `deps.require(action)` dependency, so every
route that asks for a key is covered, whatever its method. The caller is left in
`scope["state"]` for that dependency, which fails closed without it."""

from __future__ import annotations

from typing import Any

from starlette.routing import Match

from authn.service.auth import Forbidden, Unauthenticated, token_of
from authn.service.replies import reply

#: scope["state"] key holding the authenticated caller
CALLER = "authn_caller"
#: attribute that `deps.require` sets on the dependency it makes
ACTION_ATTR = "authn_action"


def _action(route: Any) -> str | None:
    """The action a route's `require(...)` dependency names, or None (no key needed)."""
    stack = [getattr(route, "dependant", None)]
    while stack:
        dep = stack.pop()
        if dep is None:
            continue
        action = getattr(dep.call, ACTION_ATTR, None)
        if action is not None:
            return action
        stack.extend(dep.dependencies)
    return None


def route_actions(routes: list[Any]) -> list[tuple[Any, str]]:
    """Every route that needs a key, with its action."""
    return [(r, a) for r in routes if (a := _action(r)) is not None]


class _Headers:
    """The request head's headers, looked up by lower-case name (as token_of needs)."""

    def __init__(self, raw: list[tuple[bytes, bytes]]) -> None:
        self.raw = raw

    def get(self, name: str) -> str | None:
        key = name.encode("latin-1")
        return next((v.decode("latin-1") for k, v in self.raw if k.lower() == key), None)


class Authenticate:
    def __init__(self, app: Any, actions: list[tuple[Any, str]]) -> None:
        self.app = app
        self.actions = actions

    def _needs(self, scope: dict) -> str | None:
        for route, action in self.actions:
            if route.matches(scope)[0] is Match.FULL:
                return action
        return None

    async def __call__(self, scope: dict, receive: Any, send: Any) -> None:
        action = self._needs(scope) if scope["type"] == "http" else None
        if action is None:
            await self.app(scope, receive, send)
            return
        runtime = scope["app"].state.runtime
        try:
            token = token_of(_Headers(scope["headers"]))
            if token is None:
                raise Unauthenticated("missing API key: send 'Authorization: Bearer <key>' or 'X-API-Key: <key>'")
            caller = await runtime.keys.caller(token, action)
        except Unauthenticated as exc:
            runtime.metrics.error(401, "unauthenticated")
            await reply(send, 401, str(exc), [(b"www-authenticate", b"Bearer")])
            return
        except Forbidden as exc:
            runtime.metrics.error(403, "forbidden")
            await reply(send, 403, str(exc))
            return
        except Exception as exc:  # noqa: BLE001 - the key store failed: fail closed, one line
            from core.errors import describe, one_line

            runtime.metrics.error(503, "system")
            await reply(send, 503, one_line(describe(exc)))
            return
        scope.setdefault("state", {})[CALLER] = caller
        await self.app(scope, receive, send)
