"""A request-head timeout for uvicorn's h11 protocol, shared by `authn serve` and the audit
witness: h11 never times out the reading of a request head, so a connection that never sends
a byte would stay open for good.

A connection is *waiting* from when it opens, and again after each response (a keep-alive
pause); it must send a complete head within `head_timeout_s()` of opening, or of its first
byte after a pause (the pause itself is bounded by uvicorn's keep-alive timeout). A subclass
says where the waiting state lives and what an expired head does; by default the state is
the connection's own and an expired head closes it.
"""

from __future__ import annotations

import asyncio

from uvicorn.protocols.http.h11_impl import H11Protocol


class HeadTimedH11(H11Protocol):
    """uvicorn's h11 protocol that calls `head_expired()` on a connection waiting for a
    request head longer than `head_timeout_s()`."""

    head_timer: asyncio.TimerHandle | None = None
    #: bytes of the head received so far (0 while nothing has come since the last response)
    head_bytes = 0
    _waiting = True

    def head_timeout_s(self) -> float:
        raise NotImplementedError

    def is_waiting(self) -> bool:
        return self._waiting

    def set_waiting(self, waiting: bool) -> None:
        self._waiting = waiting

    def head_expired(self) -> None:
        """The head did not come in time: close the connection."""
        self.transport.close()

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]  # as uvicorn's: it narrows the transport
        super().connection_made(transport)
        self.arm_head_timer()

    def connection_lost(self, exc: Exception | None) -> None:
        self.cancel_head_timer()
        super().connection_lost(exc)

    def data_received(self, data: bytes) -> None:
        if self.is_waiting():
            self.head_bytes += len(data)
            if self.head_timer is None:  # the first byte after a keep-alive pause
                self.arm_head_timer()
        super().data_received(data)

    def handle_events(self) -> None:
        cycle = self.cycle
        super().handle_events()
        if self.cycle is not cycle:  # a head was parsed: the request now counts, not the socket
            self.cancel_head_timer()
            self.head_bytes = 0
            self.set_waiting(False)

    def on_response_complete(self) -> None:
        if not self.transport.is_closing():
            self.set_waiting(True)  # before uvicorn parses a pipelined next request
        super().on_response_complete()

    def arm_head_timer(self) -> None:
        self.cancel_head_timer()
        self.head_timer = self.loop.call_later(self.head_timeout_s(), self._head_timeout)

    def cancel_head_timer(self) -> None:
        if self.head_timer is not None:
            self.head_timer.cancel()
            self.head_timer = None

    def _head_timeout(self) -> None:
        self.head_timer = None
        if not self.transport.is_closing() and self.is_waiting():
            self.head_expired()
