"""The witness endpoint over HTTP: an ASGI app (Starlette's request and response) run by
uvicorn, the stack `authn serve` runs on. What each operation answers is the endpoint's
(authn.audit.witness.Endpoint); the transport's own answers are the routes and limits:

- `GET /checkpoints?origin=O`: the endpoint's `checkpoints(O)`; 404 without an origin or
  on another path.
- `POST /add-checkpoint`: the endpoint's `add(body)`; 400 for a body over MAX_BODY_BYTES or
  without a Content-Length, or another path.
- Any other method: 501.

h11 never times out a request head, so the shared head timeout (authn.http_head) closes a connection that has not
sent a complete head within REQUEST_TIMEOUT_S of opening (or of its first byte after a
keep-alive pause); a body not received within as long again is answered 408.
"""

from __future__ import annotations

import asyncio
import os
import socket
import urllib.parse
from typing import TYPE_CHECKING, Protocol

import uvicorn
from starlette.concurrency import run_in_threadpool
from starlette.requests import ClientDisconnect, Request
from starlette.responses import PlainTextResponse

from authn.http_head import HeadTimedH11
from core.errors import SystemFault

if TYPE_CHECKING:
    from starlette.types import Receive, Scope, Send

MAX_BODY_BYTES = 1 << 16
REQUEST_TIMEOUT_S = 10.0


def _text(status: int, body: str) -> PlainTextResponse:
    return PlainTextResponse(body, status_code=status)


class Endpoint(Protocol):
    """What the witness answers, as (status, text)."""

    def checkpoints(self, origin: str) -> tuple[int, str]: ...

    def add(self, body: bytes) -> tuple[int, str]: ...


class WitnessApp:
    """The witness's two routes (ASGI) over an endpoint; its calls run in the thread pool
    (they read and lock files)."""

    def __init__(self, endpoint: Endpoint) -> None:
        self.endpoint = endpoint

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            return
        request = Request(scope, receive)
        response: PlainTextResponse | None
        if request.method == "GET":
            response = await run_in_threadpool(self._checkpoints, request)
        elif request.method == "POST":
            response = await self._post(request)
        else:
            response = _text(501, f"unsupported method {request.method}\n")
        if response is not None:
            await response(scope, receive, send)

    def _checkpoints(self, request: Request) -> PlainTextResponse:
        query = urllib.parse.parse_qs(request.scope["query_string"].decode("latin-1"))
        origin = query.get("origin", [""])[0]
        if request.scope.get("raw_path") != b"/checkpoints" or not origin:
            return _text(404, "GET /checkpoints?origin=ORIGIN\n")
        return _text(*self.endpoint.checkpoints(origin))

    async def _post(self, request: Request) -> PlainTextResponse | None:
        length = request.headers.get("content-length", "")
        if request.scope.get("raw_path") != b"/add-checkpoint" or not length.isdigit() \
                or int(length) > MAX_BODY_BYTES:
            return _text(400, "POST /add-checkpoint with a body under 64 KiB\n")
        try:
            body = await asyncio.wait_for(request.body(), REQUEST_TIMEOUT_S)
        except asyncio.TimeoutError:
            return _text(408, f"request body not received within {REQUEST_TIMEOUT_S:g} s\n")
        except ClientDisconnect:
            return None
        return _text(*await run_in_threadpool(self.endpoint.add, body))


class WitnessH11(HeadTimedH11):
    """The shared head timeout at REQUEST_TIMEOUT_S (read when a timer is armed, so a test may
    shorten it)."""

    def head_timeout_s(self) -> float:
        return REQUEST_TIMEOUT_S


def listen(host: str, port: int) -> socket.socket:
    """A listening socket on host:port (SystemFault when it cannot be had)."""
    try:
        family = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)[0][0]
        return socket.create_server((host, port), family=family, backlog=128)
    except OSError as exc:
        why = os.strerror(exc.errno) if exc.errno else str(exc)
        raise SystemFault(f"witness: cannot listen on {host}:{port} ({why})") from None


def run(endpoint: Endpoint, host: str, port: int) -> None:
    """Serve `endpoint` on host:port until interrupted."""
    sock = listen(host, port)
    config = uvicorn.Config(WitnessApp(endpoint), http=WitnessH11, ws="none", lifespan="off",
                            log_config=None, access_log=False)
    try:
        uvicorn.Server(config).run(sockets=[sock])
    finally:
        sock.close()
