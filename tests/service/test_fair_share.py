"""Slow bodies from a few addresses cannot starve another (issue 55, item 2): a per-address
limit on requests receiving a body, a fair share of request slots (an address receiving the
most bodies gives one up to a newcomer), and behind a proxy the client address from the
header the operator trusts, only from the proxies the operator names. A real server; the
client addresses are loopback addresses 127.0.0.2.. bound by the sockets (Linux)."""

from __future__ import annotations

import time

import httpx
import pytest

from lab.http_abuse import read_reply, start_slow_body
from tests.service.server import Server, server_env, start

CHECK_HEAD = (b'--b\r\nContent-Disposition: form-data; name="file"; filename="a.h5"\r\n'
              b"Content-Type: application/octet-stream\r\n\r\n")


def _addr(server: Server) -> tuple[str, int]:
    host, port = server.url.rsplit("//", 1)[1].split(":")
    return host, int(port)


def _slow_check(server: Server, token: str, source: str, headers: dict[str, str] | None = None):
    return start_slow_body(*_addr(server), "/v1/checks", {"Authorization": f"Bearer {token}",
                                                          "Content-Type": "multipart/form-data; boundary=b",
                                                          **(headers or {})}, CHECK_HEAD, source=source)


def _load(server: Server) -> dict:
    return httpx.get(f"{server.url}/readyz", timeout=30).json()["load"]


def _answered_at_once(sock, within_s: float = 1.0) -> int | None:
    """The status the server answered within `within_s`, or None while it still reads the body."""
    status, _, _ = read_reply(sock, within_s)
    return status


@pytest.fixture(scope="module")
def fair_server(sqlite_db, keys, keys_dir, tmp_path_factory) -> Server:
    """One worker, 64 request slots, slow bodies held for 60 s."""
    srv = start(sqlite_db, tmp_path_factory.mktemp("log") / "serve.log", server_env(keys_dir),
                "--max-in-flight", "64", "--upload-timeout-s", "60", "--header-timeout-s", "30")
    yield srv
    log = srv.stop()
    assert "Traceback" not in log and srv.proc.returncode == 0, log[-3000:]


def test_slow_bodies_from_eight_addresses_do_not_starve_a_ninth(fair_server, keys, returns) -> None:
    """8 addresses x 20 slow check bodies against 64 slots, then 20 real checks from a ninth.
    Before: the slow bodies held all 64 slots and the checks got 503."""
    slow = [_slow_check(fair_server, keys.operator, f"127.0.0.{2 + i // 20}") for i in range(160)]
    try:
        deadline = time.monotonic() + 10
        while _load(fair_server)["in_flight"] < 48 and time.monotonic() < deadline:
            time.sleep(0.1)
        before = _load(fair_server)
        body = returns["genuine"].read_bytes()
        statuses = []
        with httpx.Client(base_url=fair_server.url, timeout=30, headers={"Authorization": f"Bearer {keys.operator}"},
                          transport=httpx.HTTPTransport(local_address="127.0.0.10")) as ninth:
            for _ in range(20):
                statuses.append(ninth.post("/v1/checks", files={"file": ("g.h5", body, "application/x-hdf5")}
                                           ).status_code)
        after = _load(fair_server)
    finally:
        for s in slow:
            s.close()
    print(f"8 x 20 slow bodies: {statuses.count(200)}/20 checks from a ninth address answered 200; "
          f"before {before}; after {after}")
    assert statuses.count(200) >= 19, statuses
    assert before["in_flight"] >= 48, before  # the slow bodies did take most of the 64 slots
    assert after["receiving_body"] >= 40, after  # and still held them


def test_an_address_receives_at_most_its_share_of_bodies(fair_server, keys) -> None:
    """16 bodies at once per address and worker (the default): the 17th is 503 at once. Without
    the proxy options a forwarded header changes nothing (uvicorn believed one from 127.0.0.1)."""
    def slow(i: int):
        return _slow_check(fair_server, keys.operator, "127.0.0.1", {"X-Forwarded-For": f"10.1.0.{i}"})

    slow_bodies = [slow(i) for i in range(16)]
    try:
        time.sleep(0.5)
        extra = slow(16)
        with extra:
            status = _answered_at_once(extra, 5.0)
        held = _answered_at_once(slow_bodies[0], 0.5)
    finally:
        for s in slow_bodies:
            s.close()
    assert status == 503 and held is None, (status, held)


@pytest.fixture(scope="module")
def proxy_server(sqlite_db, keys, keys_dir, tmp_path_factory) -> Server:
    """Behind a proxy at 127.0.0.1 that names the client in X-Forwarded-For; 1 body per address."""
    srv = start(sqlite_db, tmp_path_factory.mktemp("log") / "serve.log", server_env(keys_dir),
                "--trusted-proxy-header", "X-Forwarded-For", "--trusted-proxies", "127.0.0.1/32",
                "--max-bodies-per-client", "1", "--upload-timeout-s", "30", "--header-timeout-s", "30")
    yield srv
    log = srv.stop()
    assert "Traceback" not in log and srv.proc.returncode == 0, log[-3000:]


def test_the_forwarded_address_counts_only_from_a_trusted_proxy(proxy_server, keys) -> None:
    def slow(source: str, forwarded: str):
        return _slow_check(proxy_server, keys.operator, source, {"X-Forwarded-For": forwarded})

    held = [slow("127.0.0.1", "10.0.0.1"), slow("127.0.0.1", "10.0.0.2"),  # two clients behind the proxy
            slow("127.0.0.5", "10.0.0.3")]  # not a proxy: its header is ignored
    try:
        time.sleep(0.5)
        same_client = slow("127.0.0.1", "10.0.0.2, 10.0.0.1")  # the left entry is the client's own word
        same_peer = slow("127.0.0.5", "10.0.0.4")
        statuses = [_answered_at_once(s, 5.0) for s in (same_client, same_peer)]
        still = [_answered_at_once(s, 0.3) for s in held]
    finally:
        for s in [*held, same_client, same_peer]:
            s.close()
    assert statuses == [503, 503] and still == [None, None, None], (statuses, still)
