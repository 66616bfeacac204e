"""The client address per-address limits count (authn/service/clients.py): a forwarded header
only from a trusted proxy, and then its rightmost entry that is not a trusted proxy."""

from __future__ import annotations

import pytest

from authn.service.clients import ClientAddress, parse_networks


def _scope(peer: str, *forwarded: str) -> dict:
    return {"client": (peer, 4242), "headers": [(b"x-forwarded-for", f.encode()) for f in forwarded]}


def test_a_forwarded_header_is_believed_only_from_a_trusted_proxy() -> None:
    clients = ClientAddress("x-forwarded-for", parse_networks("10.0.0.0/8, 192.0.2.7"))
    assert clients.of(_scope("10.1.2.3", "198.51.100.1")) == "198.51.100.1"
    assert clients.of(_scope("192.0.2.7", "198.51.100.1")) == "198.51.100.1"
    assert clients.of(_scope("192.0.2.8", "198.51.100.1")) == "192.0.2.8"  # not a proxy: ignored
    assert clients.of(_scope("10.1.2.3")) == "10.1.2.3"  # no header: the proxy itself


def test_the_client_is_the_rightmost_entry_that_is_not_a_proxy() -> None:
    clients = ClientAddress("x-forwarded-for", parse_networks("10.0.0.0/8"))
    assert clients.of(_scope("10.0.0.1", "203.0.113.9, 198.51.100.1, 10.0.0.2")) == "198.51.100.1"
    assert clients.of(_scope("10.0.0.1", "203.0.113.9", "198.51.100.1")) == "198.51.100.1"  # two header lines
    assert clients.of(_scope("10.0.0.1", "2001:db8::1")) == "2001:db8::1"
    assert clients.of(_scope("10.0.0.1", "203.0.113.9, not-an-address")) == "10.0.0.1"  # garbage: not believed
    assert clients.of(_scope("10.0.0.1", "10.0.0.3, 10.0.0.2")) == "10.0.0.1"  # only proxies: the peer


def test_without_proxies_the_peer_is_the_client() -> None:
    assert ClientAddress().of(_scope("127.0.0.1", "198.51.100.1")) == "127.0.0.1"


def test_bad_networks_are_named() -> None:
    with pytest.raises(ValueError, match="'10.0.0.0/33'"):
        parse_networks("10.0.0.1,10.0.0.0/33")
    assert len(parse_networks(" 10.0.0.0/8 , ::1 ,")) == 2


@pytest.mark.parametrize("args, named", [
    (["--trusted-proxy-header", "X-Forwarded-For"], "go together"),
    (["--trusted-proxies", "10.0.0.0/8"], "go together"),
    (["--trusted-proxy-header", "X-Forwarded-For", "--trusted-proxies", "10.0.0.0/33"], "'10.0.0.0/33'"),
    (["--trusted-proxy-header", "X Forwarded", "--trusted-proxies", "10.0.0.0/8"], "header name"),
])
def test_serve_refuses_bad_proxy_options(capsys, args, named) -> None:
    """Exit 2 with one line before anything starts."""
    from authn.cli import main

    assert main(["serve", "--port", "1", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert named in err and "\n" not in err and "Traceback" not in err, err
