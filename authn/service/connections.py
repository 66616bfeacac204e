"""What one worker lets a connection hold before it has asked for anything.

uvicorn (h11) never times out the reading of a request head: a connection that never sends a
byte stays open, and its `limit_concurrency` counts open connections, so 600 idle sockets
made both workers of `authn serve --workers 2` answer every check 503. Here, per worker:

- **Header timeout:** a connection must send a complete request head within
  `header_timeout_s` of opening, and of its first byte after a keep-alive pause (the pause
  itself is bounded by uvicorn's keep-alive timeout). Otherwise it is closed (with a 408 if
  part of a head had arrived, silently if nothing had).
- **Waiting connections are evictable, not counted as load:** a connection that has not yet
  sent its head (or sits idle between keep-alive requests) is *waiting*. Requests in flight
  are limited separately (`max_in_flight` per worker, `max_connections_per_client` per
  address, a fair share, `max_bodies_per_client` receiving a body; 503 beyond, through
  `authn.service.limits`), so idle sockets never make a real request 503.
- **Per client address:** at most `max_connections_per_client` open connections. When an
  address goes over, its oldest *waiting* connections are closed until it is back within the
  limit. That trim runs TRIM_DELAY_S after the connection that went over was accepted, not at
  once: asyncio accepts a whole burst of connections before it reads any of them, and a real
  client whose request head is already in the socket must have become *active* (head parsed)
  by then, or a burst of idle sockets accepted after it would make it the oldest waiting one.
  So a flood of idle sockets from one address holds at most that many connections of a
  worker, yet cannot lock out a real client from the same address (the loopback tests rely on
  this: every client there is 127.0.0.1).
- **Per worker:** at most `max_connections` open connections, trimmed the same way (the
  oldest waiting connection of any address goes first). Between trims a burst may go over,
  up to HARD_FACTOR times the limit; a connection beyond that is closed at once (`refused`).

The guard is per process (each worker has its own event loop); `/readyz` reads its
`snapshot()`. Everything here runs on the worker's event loop thread, so plain counters suffice.
"""

from __future__ import annotations

import asyncio
import json
import logging
from collections import OrderedDict
from dataclasses import asdict, dataclass
from typing import Any

import h11

from authn.http_head import HeadTimedH11

log = logging.getLogger("authn.service")


@dataclass(frozen=True)
class ConnectionLimits:
    #: seconds a connection may take to send a complete request head
    header_timeout_s: float = 5.0
    #: open connections per worker
    max_connections: int = 1024
    #: open connections per client address per worker
    max_connections_per_client: int = 64
    #: requests in the application at once per worker (503 beyond); health probes are not counted
    max_in_flight: int = 256
    #: requests of one client address receiving their body at once per worker (503 beyond)
    max_bodies_per_client: int = 16

    def __post_init__(self) -> None:
        if self.header_timeout_s <= 0:
            raise ValueError("header_timeout_s must be positive")
        if not 1 <= self.max_connections_per_client <= self.max_connections:
            raise ValueError("max_connections_per_client must be between 1 and max_connections")
        if self.max_in_flight < 1:
            raise ValueError("max_in_flight must be at least 1")
        if self.max_bodies_per_client < 1:
            raise ValueError("max_bodies_per_client must be at least 1")


#: seconds between accepting a connection that goes over a limit and closing the oldest waiting ones
TRIM_DELAY_S = 0.05
#: open connections may exceed max_connections by this factor between trims; beyond, refused at once
HARD_FACTOR = 2


class ConnectionGuard:
    """The open connections of one worker: which are waiting for a head, per address."""

    def __init__(self, limits: ConnectionLimits) -> None:
        self.limits = limits
        self.open: dict[Any, str] = {}  # connection -> client address
        self.per_client: dict[str, int] = {}
        self.waiting: OrderedDict[Any, None] = OrderedDict()  # oldest first
        self.waiting_by_client: dict[str, OrderedDict[Any, None]] = {}
        self.in_flight = 0
        self.in_flight_by_client: dict[str, int] = {}
        self.bodies = 0
        self.bodies_by_client: dict[str, OrderedDict[Any, None]] = {}  # requests receiving a body, oldest first
        self.counts = {"header_timeouts": 0, "evicted": 0, "refused": 0, "busy": 0, "preempted": 0}
        self._trim: asyncio.TimerHandle | None = None

    # connection life
    def admit(self, conn: Any, addr: str) -> bool:
        """Register a new connection (waiting for its head); False if it must be closed now."""
        if len(self.open) >= HARD_FACTOR * self.limits.max_connections:
            self.counts["refused"] += 1
            return False
        self.open[conn] = addr
        self.per_client[addr] = self.per_client.get(addr, 0) + 1
        self.set_waiting(conn)
        return True

    def _trim_soon(self, addr: str) -> None:
        over = (self.per_client[addr] > self.limits.max_connections_per_client
                or len(self.open) > self.limits.max_connections)
        if over and self._trim is None:
            self._trim = asyncio.get_running_loop().call_later(TRIM_DELAY_S, self.trim)

    def trim(self) -> None:
        """Close the oldest waiting connections of every address over its limit, then of any
        address while the worker is over its limit."""
        self._trim = None
        cap = self.limits.max_connections_per_client
        for addr in [a for a, n in self.per_client.items() if n > cap]:
            while self.per_client.get(addr, 0) > cap and self._evict_oldest(self.waiting_by_client.get(addr)):
                pass
        while len(self.open) > self.limits.max_connections and self._evict_oldest(self.waiting):
            pass

    def set_waiting(self, conn: Any) -> None:
        addr = self.open.get(conn)
        if addr is None:
            return
        self.waiting[conn] = None
        self.waiting.move_to_end(conn)
        self.waiting_by_client.setdefault(addr, OrderedDict())[conn] = None
        self.waiting_by_client[addr].move_to_end(conn)
        self._trim_soon(addr)  # a new connection, or one that could not be trimmed while active

    def set_active(self, conn: Any) -> None:
        addr = self.open.get(conn)
        if addr is None:
            return
        self.waiting.pop(conn, None)
        mine = self.waiting_by_client.get(addr)
        if mine is not None:
            mine.pop(conn, None)
            if not mine:
                del self.waiting_by_client[addr]

    def is_waiting(self, conn: Any) -> bool:
        return conn in self.waiting

    def release(self, conn: Any) -> None:
        """The connection is closed (or being closed): forget it. Idempotent."""
        self.set_active(conn)
        addr = self.open.pop(conn, None)
        if addr is None:
            return
        left = self.per_client[addr] - 1
        if left:
            self.per_client[addr] = left
        else:
            del self.per_client[addr]

    def _evict_oldest(self, waiting: OrderedDict[Any, None] | None) -> bool:
        if not waiting:
            return False
        victim = next(iter(waiting))
        self.release(victim)
        victim.evict()
        self.counts["evicted"] += 1
        return True

    # what /readyz reports
    def active(self) -> int:
        return len(self.open) - len(self.waiting)

    def saturated(self) -> bool:
        """New requests would get 503 (in flight at the limit), or every connection slot holds a
        request (no waiting connection can make room for a new one)."""
        return self.in_flight >= self.limits.max_in_flight or self.active() >= self.limits.max_connections

    # requests (RequestLimit)
    def request_started(self, addr: str) -> str | None:
        """Count a request in; or say why it must get 503.

        Fair share: an address holding m requests gets another only while more than m slots
        are free, so one address alone takes at most half. When that refuses it, the address
        receiving the most bodies, if it holds at least two more requests than this one, has
        its newest body cut (503) and this request takes the slot: slow bodies from a few
        addresses cannot keep another address out."""
        free = self.limits.max_in_flight - self.in_flight
        mine = self.in_flight_by_client.get(addr, 0)
        if mine >= self.limits.max_connections_per_client:
            return (f"{mine} requests from your address in flight on this worker "
                    f"(limit {self.limits.max_connections_per_client})")
        if free <= mine and not self._preempt_for(mine):
            if free <= 0:
                return f"{self.in_flight} requests in flight on this worker (limit {self.limits.max_in_flight})"
            return f"{mine} requests from your address in flight and {free} free on this worker (fair share)"
        self.in_flight += 1
        self.in_flight_by_client[addr] = mine + 1
        return None

    def request_done(self, addr: str) -> None:
        self.in_flight -= 1
        left = self.in_flight_by_client[addr] - 1
        if left:
            self.in_flight_by_client[addr] = left
        else:
            del self.in_flight_by_client[addr]

    def _preempt_for(self, mine: int) -> bool:
        """Cut the newest body of the address receiving the most, if it holds at least two more
        requests than `mine`; whether one was cut (its slot is freed as it unwinds)."""
        if not self.bodies_by_client:
            return False
        top = max(self.bodies_by_client, key=lambda a: len(self.bodies_by_client[a]))
        if len(self.bodies_by_client[top]) < mine + 2:
            return False
        victim = next(reversed(self.bodies_by_client[top]))
        self.body_done(top, victim)
        victim.preempt()
        self.counts["preempted"] += 1
        return True

    def body_started(self, addr: str, reading: Any) -> str | None:
        """Count `reading` (a request of `addr` receiving its body; `preempt()` cuts it) in, or
        say why it must get 503."""
        mine = self.bodies_by_client.setdefault(addr, OrderedDict())
        if len(mine) >= self.limits.max_bodies_per_client:
            return (f"{len(mine)} requests from your address receiving a body on this worker "
                    f"(limit {self.limits.max_bodies_per_client})")
        self.bodies += 1
        mine[reading] = None
        return None

    def body_done(self, addr: str, reading: Any) -> None:
        """`reading` has its body, or was cut, or ended. Idempotent."""
        mine = self.bodies_by_client.get(addr)
        if mine is None or reading not in mine:
            return
        del mine[reading]
        self.bodies -= 1
        if not mine:
            del self.bodies_by_client[addr]

    def snapshot(self) -> dict[str, Any]:
        return {"connections": len(self.open), "waiting_for_head": len(self.waiting), "in_flight": self.in_flight,
                "receiving_body": self.bodies, "clients": len(self.per_client), **asdict(self.limits),
                **self.counts}


_GUARD: ConnectionGuard | None = None


def configure(limits: ConnectionLimits) -> ConnectionGuard:
    """Make this process's guard (the worker calls it before uvicorn starts)."""
    global _GUARD
    _GUARD = ConnectionGuard(limits)
    return _GUARD


def current() -> ConnectionGuard | None:
    """This process's guard, or None when the app runs outside `authn serve` (no limits)."""
    return _GUARD


class GuardedH11Protocol(HeadTimedH11):
    """uvicorn's h11 protocol with a request-head timeout, registered with this worker's guard
    (which holds the waiting state).

    uvicorn's own `limit_concurrency` (open connections + tasks) is off: the guard counts
    connections, `RequestLimit` counts requests."""

    def __init__(self, config: Any, server_state: Any, app_state: dict[str, Any],
                 _loop: asyncio.AbstractEventLoop | None = None) -> None:
        super().__init__(config, server_state, app_state, _loop)
        guard = current()
        assert guard is not None, "connections.configure() before serving"
        self.guard = guard
        self.limit_concurrency = None

    def head_timeout_s(self) -> float:
        return self.guard.limits.header_timeout_s

    def is_waiting(self) -> bool:
        return self.guard.is_waiting(self)

    def set_waiting(self, waiting: bool) -> None:
        if waiting:
            self.guard.set_waiting(self)
        else:
            self.guard.set_active(self)

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        addr = self.client[0] if self.client else ""
        if not self.guard.admit(self, addr):
            self.cancel_head_timer()
            transport.close()

    def connection_lost(self, exc: Exception | None) -> None:
        self.guard.release(self)
        super().connection_lost(exc)

    def evict(self) -> None:
        """The guard needs the room: close this waiting connection."""
        self.cancel_head_timer()
        if not self.transport.is_closing():
            self.transport.close()

    def head_expired(self) -> None:
        """Count it, and close with a 408 if part of a head had arrived."""
        self.guard.counts["header_timeouts"] += 1
        self.guard.release(self)
        if self.head_bytes and self.conn.our_state is h11.IDLE:
            body = json.dumps({"error": f"request head not received within "
                                        f"{self.guard.limits.header_timeout_s:g} s"}).encode()
            self.transport.write(b"HTTP/1.1 408 Request Timeout\r\ncontent-type: application/json\r\n"
                                 b"content-length: " + str(len(body)).encode() + b"\r\nconnection: close\r\n\r\n"
                                 + body)
        self.transport.close()
