"""The connection guard's bookkeeping (authn/service/connections.py) without a server: which
connection is closed to make room, when a request gets 503, when a worker is saturated."""

from __future__ import annotations

import asyncio

import pytest

from authn.service import connections
from authn.service.connections import ConnectionGuard, ConnectionLimits


class Conn:
    def __init__(self, name: str) -> None:
        self.name = name
        self.evicted = False

    def evict(self) -> None:
        self.evicted = True

    def __repr__(self) -> str:
        return self.name


def _run(fn) -> None:
    """Run fn(guard-making helpers) on an event loop (admit schedules its trims there)."""
    async def main() -> None:
        await fn()

    asyncio.run(main())


async def _settle() -> None:
    await asyncio.sleep(connections.TRIM_DELAY_S * 3)


def test_an_address_over_its_limit_loses_its_oldest_waiting_connection() -> None:
    async def case() -> None:
        g = ConnectionGuard(ConnectionLimits(max_connections=100, max_connections_per_client=3))
        a = [Conn(f"a{i}") for i in range(3)]
        other = Conn("b0")
        for c in a:
            assert g.admit(c, "10.0.0.1")
        assert g.admit(other, "10.0.0.2")
        g.set_active(a[0])  # a0 sent its head: a request, not an idle socket
        real = Conn("a-real")
        assert g.admit(real, "10.0.0.1")  # 4 > 3: trimmed after TRIM_DELAY_S ...
        g.set_active(real)  # ... by which time the real client's head has been read
        await _settle()
        assert [c.evicted for c in a] == [False, True, False] and not real.evicted and not other.evicted
        assert g.per_client == {"10.0.0.1": 3, "10.0.0.2": 1} and g.counts["evicted"] == 1
        g.release(a[1])  # its connection_lost comes later: nothing counted twice
        assert g.per_client["10.0.0.1"] == 3

    _run(case)


def test_a_keep_alive_connection_that_just_answered_is_the_newest_waiting() -> None:
    async def case() -> None:
        g = ConnectionGuard(ConnectionLimits(max_connections=100, max_connections_per_client=2))
        old, flood = Conn("old"), Conn("flood")
        g.admit(old, "a")
        g.admit(flood, "a")
        g.set_active(old)
        g.set_waiting(old)  # response done, idle between requests: newer than `flood`
        g.admit(Conn("new"), "a")
        await _settle()
        assert flood.evicted and not old.evicted

    _run(case)


def test_the_worker_limit_closes_the_oldest_waiting_of_any_address() -> None:
    async def case() -> None:
        g = ConnectionGuard(ConnectionLimits(max_connections=3, max_connections_per_client=3))
        conns = [Conn(f"c{i}") for i in range(3)]
        for i, c in enumerate(conns):
            g.admit(c, f"10.0.0.{i}")
        g.set_active(conns[0])
        g.admit(Conn("c3"), "10.0.0.9")
        await _settle()
        assert [c.evicted for c in conns] == [False, True, False] and len(g.open) == 3

    _run(case)


def test_active_connections_are_never_closed_and_a_burst_beyond_twice_the_limit_is_refused() -> None:
    async def case() -> None:
        g = ConnectionGuard(ConnectionLimits(max_connections=2, max_connections_per_client=2))
        conns = [Conn(f"c{i}") for i in range(4)]
        for c in conns:
            assert g.admit(c, "a")
            g.set_active(c)
        assert not g.admit(Conn("c4"), "a") and g.counts["refused"] == 1  # 2 x max_connections open
        await _settle()
        assert not any(c.evicted for c in conns) and g.saturated()
        for c in conns[:3]:
            g.set_waiting(c)  # idle now: trimmed back within the limits
        await _settle()
        assert [c.evicted for c in conns] == [True, True, False, False] and not g.saturated()

    _run(case)


def test_requests_in_flight_per_worker_and_per_address() -> None:
    g = ConnectionGuard(ConnectionLimits(max_connections=10, max_connections_per_client=2, max_in_flight=3))
    assert g.request_started("a") is None and g.request_started("a") is None
    assert "from your address" in g.request_started("a")  # one address: at most 2
    assert not g.saturated() and g.request_started("b") is None
    assert g.in_flight == 3 and g.saturated()
    assert "requests in flight on this worker (limit 3)" in g.request_started("c")
    g.request_done("a")
    assert not g.saturated() and g.request_started("c") is None
    for addr in ("a", "b", "c"):
        g.request_done(addr)
    assert g.in_flight == 0 and g.in_flight_by_client == {}


def test_limits_are_checked() -> None:
    with pytest.raises(ValueError):
        ConnectionLimits(max_connections=10, max_connections_per_client=11)
    with pytest.raises(ValueError):
        ConnectionLimits(header_timeout_s=0)
    with pytest.raises(ValueError):
        ConnectionLimits(max_in_flight=0)


class Body:
    """A request receiving its body, as `limits._Reading` registers it."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.preempted = False

    def preempt(self) -> None:
        self.preempted = True

    def __repr__(self) -> str:
        return self.name


def test_an_address_gets_another_slot_only_while_more_are_free_than_it_holds() -> None:
    g = ConnectionGuard(ConnectionLimits(max_connections=100, max_connections_per_client=100, max_in_flight=8))
    assert [g.request_started("a") for _ in range(5)].count(None) == 4  # alone: half the slots
    assert "fair share" in g.request_started("a")
    assert g.request_started("b") is None and g.request_started("b") is None
    assert "fair share" in g.request_started("b")  # 4 + 2 held, 2 free: b holds 2
    assert g.request_started("c") is None and g.request_started("d") is None
    assert "requests in flight on this worker (limit 8)" in g.request_started("e")  # nothing receiving a body


def test_the_address_receiving_the_most_bodies_gives_one_up_to_a_newcomer() -> None:
    g = ConnectionGuard(ConnectionLimits(max_connections=100, max_connections_per_client=100, max_in_flight=5,
                                         max_bodies_per_client=3))
    bodies = {addr: [Body(f"{addr}{i}") for i in range(2)] for addr in ("a", "b")}
    for addr, mine in bodies.items():
        for body in mine:
            assert g.request_started(addr) is None and g.body_started(addr, body) is None
    assert g.request_started("c") is None  # the last slot (a request whose body is in)
    assert g.in_flight == 5 and g.bodies == 4
    assert g.request_started("d") is None  # full: a, first of the largest, gives up its newest body
    assert [b.preempted for b in bodies["a"] + bodies["b"]] == [False, True, False, False]
    assert g.bodies == 3 and g.counts["preempted"] == 1
    g.body_done("a", bodies["a"][1])  # its request unwinds: idempotent
    g.request_done("a")
    assert g.bodies == 3 and g.in_flight == 5
    assert "requests in flight" in g.request_started("b")  # b holds 2: nobody holds 2 more than that
    assert g.request_started("e") is None and bodies["b"][1].preempted  # b holds 2 >= 0 + 2


def test_an_address_receives_at_most_its_bodies() -> None:
    g = ConnectionGuard(ConnectionLimits(max_bodies_per_client=2))
    first, second = Body("1"), Body("2")
    assert g.body_started("a", first) is None and g.body_started("a", second) is None
    assert "receiving a body on this worker (limit 2)" in g.body_started("a", Body("3"))
    assert g.body_started("b", Body("4")) is None
    g.body_done("a", first)
    assert g.body_started("a", Body("5")) is None and g.bodies == 3
