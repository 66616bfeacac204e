"""Body limits and request slots, enforced in pure ASGI layers around the app.

`BodyLimits` gives every request a body limit and a body timeout: the uploads (routes that
take files) `max_upload_bytes` and the upload timeout, routes that take a JSON body (and
unknown paths) the small `max_body_bytes` and the body timeout, routes that take no body 0
bytes. A declared Content-Length over the limit is refused before a byte is read, a chunked
body as soon as it passes the limit (413); a body that takes longer than its timeout to
arrive is cut off (408), so a slow client holds one connection, never a worker; an upload
that is not multipart/form-data gets 415. An address
may have at most `max_bodies_per_client` requests receiving a body on a worker at once (503
beyond, before the body is read), and the guard may cut one to make room for another
address. It runs after `gate.Authenticate`: a caller without a valid key never reaches it.

`RequestLimit` bounds the requests in the application at once per worker and per client
address, and gives each address a fair share (503 with Retry-After beyond, see
`connections.ConnectionGuard.request_started`): it counts requests, not sockets, so
connections that have not sent a request head never make a real request 503. Health probes
are exempt, so `/readyz` can say that the worker is saturated."""

from __future__ import annotations

import asyncio
import time
from dataclasses import dataclass
from typing import Any

from authn.service.clients import ClientAddress
from authn.service.replies import reply

#: room for the multipart boundaries, part headers and the small form fields
FORM_OVERHEAD = 64 * 1024
#: not counted by RequestLimit (cheap, and /readyz must answer when the worker is saturated)
PROBE_PATHS = ("/healthz", "/readyz")


@dataclass(frozen=True)
class BodyRule:
    """One kind of body: its limit in bytes, its timeout, and how the errors name it."""

    limit: int
    timeout_s: float
    noun: str  # "upload", "body", or "body (this endpoint takes none)"
    stated: int  # the limit the 413 states (an upload's without the form's overhead)
    multipart: bool = False  # 415 unless multipart/form-data

    def too_big(self) -> str:
        return f"{self.noun} larger than the limit of {self.stated} bytes"

    def too_slow(self) -> str:
        return f"{self.noun} not received within {self.timeout_s:g} s"


def body_rules(routes: list[Any], upload: BodyRule, other: BodyRule) -> list[tuple[Any, BodyRule]]:
    """Each route's rule: `upload` for a route that takes files, `other` for one that takes a
    JSON body, a limit of 0 for one that takes no body."""
    from fastapi.params import File

    none = BodyRule(0, other.timeout_s, "body (this endpoint takes none)", 0)
    rules = []
    for route in routes:
        params = route.dependant.body_params
        rules.append((route, upload if any(isinstance(p.field_info, File) for p in params) else
                      other if params else none))
    return rules


class BodyLimits:
    def __init__(self, app: Any, rules: list[tuple[Any, BodyRule]], other: BodyRule, clients: ClientAddress) -> None:
        self.app = app
        self.rules, self.other, self.clients = rules, other, clients

    def _rule(self, scope: dict) -> BodyRule:
        from starlette.routing import Match

        return next((rule for route, rule in self.rules if route.matches(scope)[0] is Match.FULL), self.other)

    async def __call__(self, scope: dict, receive: Any, send: Any) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope["headers"]}
        rule = self._rule(scope)
        if rule.multipart and not headers.get("content-type", "").lower().startswith("multipart/form-data"):
            await reply(send, 415, "upload the recorded return as multipart/form-data (field 'file')")
            return
        declared = headers.get("content-length", "")
        chunked = "chunked" in headers.get("transfer-encoding", "").lower()
        if (declared.isdigit() and int(declared) > rule.limit) or (chunked and rule.limit == 0):
            await reply(send, 413, rule.too_big())
            return
        if not (chunked or declared.strip("0")):
            await self.app(scope, receive, send)  # no body to wait for
            return
        await self._with_body(scope, receive, send, rule)

    async def _with_body(self, scope: dict, receive: Any, send: Any, rule: BodyRule) -> None:
        from authn.service.connections import current

        guard, addr = current(), self.clients.of(scope)
        reading = _Reading(receive, rule, guard, addr)
        if guard is not None:
            refused = guard.body_started(addr, reading)
            if refused is not None:
                guard.counts["busy"] += 1
                await reply(send, 503, f"server busy: {refused}; retry", [(b"retry-after", b"1")])
                return

        async def guarded_send(msg: dict) -> None:
            if reading.cut is None:
                await send(msg)

        try:
            await self.app(scope, reading.receive, guarded_send)
        except Exception:
            if reading.cut is None:
                raise
        finally:
            reading.done()
        if reading.cut is not None:
            await reply(send, *_CUT[reading.cut](rule))


#: the answer to a body cut off: over the limit, too slow, or preempted for another address
_CUT: dict[str, Any] = {
    "over": lambda rule: (413, rule.too_big()),
    "slow": lambda rule: (408, rule.too_slow()),
    "preempted": lambda rule: (503, "server busy: your slowest body was cut to make room for another address; "
                                    "retry", [(b"retry-after", b"1")])}


class _Reading:
    """One request's body as the app reads it: counted against the limit, against the
    deadline until its last chunk, and in the guard's bodies in progress (which may preempt it)."""

    def __init__(self, receive: Any, rule: BodyRule, guard: Any, addr: str) -> None:
        self._receive, self.rule, self.guard, self.addr = receive, rule, guard, addr
        self.deadline = time.monotonic() + rule.timeout_s
        self.received = 0
        self.cut: str | None = None  # why the app was told the client left (BodyLimits answers)
        self.in_body = True
        self._preempted = asyncio.get_running_loop().create_future()

    def preempt(self) -> None:
        """The guard needs this slot for another address: cut the body at once."""
        if not self._preempted.done():
            self._preempted.set_result(None)

    async def receive(self) -> dict:
        if self.cut is not None:
            return {"type": "http.disconnect"}
        if not self.in_body:
            return await self._receive()  # the body is in: only a disconnect is left to hear
        arriving = asyncio.ensure_future(self._receive())
        await asyncio.wait((arriving, self._preempted), timeout=max(self.deadline - time.monotonic(), 0.001),
                           return_when=asyncio.FIRST_COMPLETED)
        if not arriving.done():
            arriving.cancel()
            return self._cut("preempted" if self._preempted.done() else "slow")
        msg = arriving.result()
        if msg["type"] == "http.request":
            self.received += len(msg.get("body", b""))
            if self.received > self.rule.limit:
                return self._cut("over")  # the app stops reading
            if not msg.get("more_body", False):
                self.done()
        return msg

    def _cut(self, why: str) -> dict:
        self.cut = why
        self.done()
        return {"type": "http.disconnect"}

    def done(self) -> None:
        """The body phase is over (complete, cut, or the request ended): count it out once."""
        if self.in_body:
            self.in_body = False
            if self.guard is not None:
                self.guard.body_done(self.addr, self)


class RequestLimit:
    """At most `max_in_flight` requests in the app at once per worker, at most
    `max_connections_per_client` of them from one address, and each address its fair share
    (this worker's connection guard)."""

    def __init__(self, app: Any, clients: ClientAddress) -> None:
        self.app = app
        self.clients = clients

    async def __call__(self, scope: dict, receive: Any, send: Any) -> None:
        from authn.service.connections import current

        guard = current()
        if guard is None or scope["type"] != "http" or scope["path"] in PROBE_PATHS:
            await self.app(scope, receive, send)
            return
        addr = self.clients.of(scope)
        refused = guard.request_started(addr)
        if refused is not None:
            guard.counts["busy"] += 1
            runtime = getattr(getattr(scope.get("app"), "state", None), "runtime", None)
            if runtime is not None:
                runtime.metrics.error(503, "busy")
            await reply(send, 503, f"server busy: {refused}; retry", [(b"retry-after", b"1")])
            return
        try:
            await self.app(scope, receive, send)
        finally:
            guard.request_done(addr)
