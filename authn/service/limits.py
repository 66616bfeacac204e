"""Upload limits enforced while the body streams in (ASGI middleware): a declared
Content-Length over the limit is refused before a byte is read, a chunked body as soon as it
passes the limit (413); a body that takes longer than the upload timeout to arrive is cut off
(408), so a slow client holds one connection, never a worker; a check upload that is not
multipart/form-data gets 415.

`RequestLimit` bounds the requests in the application at once per worker and per client
address (503 beyond, with Retry-After): it counts requests, not sockets, so connections that have not sent a request
head (authn.service.connections) never make a real request 503. Health probes are exempt, so
`/readyz` can say that the worker is saturated."""

from __future__ import annotations

import asyncio
import json
import time
from typing import Any

UPLOAD_PATHS = ("/v1/checks", "/v1/checks:batch")
#: room for the multipart boundaries, part headers and the serial field
FORM_OVERHEAD = 64 * 1024


#: not counted by RequestLimit (cheap, and /readyz must answer when the worker is saturated)
PROBE_PATHS = ("/healthz", "/readyz")


async def _reply(send: Any, status: int, message: str, headers: list[tuple[bytes, bytes]] = ()) -> None:
    body = json.dumps({"error": message}).encode()
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode()),
                            (b"connection", b"close"), *headers]})
    await send({"type": "http.response.body", "body": body})


class UploadLimits:
    def __init__(self, app: Any, max_upload_bytes: int, timeout_s: float) -> None:
        self.app = app
        self.timeout_s = timeout_s
        self.limit = max_upload_bytes + FORM_OVERHEAD
        self.max_upload_bytes = max_upload_bytes

    async def __call__(self, scope: dict, receive: Any, send: Any) -> None:
        if scope["type"] != "http" or scope["method"] != "POST" or scope["path"] not in UPLOAD_PATHS:
            await self.app(scope, receive, send)
            return
        headers = {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope["headers"]}
        too_big = f"upload larger than the limit of {self.max_upload_bytes} bytes"
        if not headers.get("content-type", "").lower().startswith("multipart/form-data"):
            await _reply(send, 415, "upload the recorded return as multipart/form-data (field 'file')")
            return
        declared = headers.get("content-length", "")
        if declared.isdigit() and int(declared) > self.limit:
            await _reply(send, 413, too_big)
            return
        state: dict[str, Any] = {"received": 0, "over": False, "slow": False}
        deadline = time.monotonic() + self.timeout_s

        async def limited_receive() -> dict:
            try:
                msg = await asyncio.wait_for(receive(), max(deadline - time.monotonic(), 0.001))
            except asyncio.TimeoutError:
                state["slow"] = state["over"] = True
                return {"type": "http.disconnect"}
            if msg["type"] == "http.request":
                state["received"] += len(msg.get("body", b""))
                if state["received"] > self.limit:
                    state["over"] = True
                    return {"type": "http.disconnect"}  # the app stops reading; we answer below
            return msg

        async def guarded_send(msg: dict) -> None:
            if not state["over"]:
                await send(msg)

        try:
            await self.app(scope, limited_receive, guarded_send)
        except Exception:
            if not state["over"]:
                raise
        if state["slow"]:
            await _reply(send, 408, f"upload not received within {self.timeout_s:g} s")
        elif state["over"]:
            await _reply(send, 413, too_big)


class RequestLimit:
    """At most `max_in_flight` requests in the app at once per worker, and at most
    `max_connections_per_client` of them from one address (this worker's connection guard)."""

    def __init__(self, app: Any) -> None:
        self.app = app

    async def __call__(self, scope: dict, receive: Any, send: Any) -> None:
        from authn.service.connections import current

        guard = current()
        if guard is None or scope["type"] != "http" or scope["path"] in PROBE_PATHS:
            await self.app(scope, receive, send)
            return
        addr = (scope.get("client") or ("",))[0]
        refused = guard.request_started(addr)
        if refused is not None:
            guard.counts["busy"] += 1
            runtime = getattr(getattr(scope.get("app"), "state", None), "runtime", None)
            if runtime is not None:
                runtime.metrics.error(503, "busy")
            await _reply(send, 503, f"server busy: {refused}; retry", [(b"retry-after", b"1")])
            return
        try:
            await self.app(scope, receive, send)
        finally:
            guard.request_done(addr)
