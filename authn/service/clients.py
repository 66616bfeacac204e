"""Which client a request comes from: the TCP peer, or, when the peer is a proxy the operator
trusts (`--trusted-proxies`), the address that proxy names in the header the operator chose
(`--trusted-proxy-header`, e.g. X-Forwarded-For). Per-address limits count this address.

A forwarded header is a list each proxy appends to, so only its right end is the proxies'
word: the client is the rightmost entry that is not itself a trusted proxy. Entries to its
left were written by the client and are never believed. A header from an untrusted peer is
ignored, as is a malformed entry (the proxy's own address is used then)."""

from __future__ import annotations

import ipaddress
from dataclasses import dataclass
from functools import lru_cache

Network = ipaddress.IPv4Network | ipaddress.IPv6Network


def parse_networks(text: str) -> tuple[Network, ...]:
    """`CIDR,CIDR,...` (a bare address is a /32 or /128); ValueError names a bad entry."""
    nets = []
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        try:
            nets.append(ipaddress.ip_network(part, strict=False))
        except ValueError:
            raise ValueError(f"not an address or CIDR network: {part!r}") from None
    return tuple(nets)


@dataclass(frozen=True)
class ClientAddress:
    """The client address of a request, through trusted proxies only."""

    header: str | None = None  # lower-case header name, e.g. "x-forwarded-for"
    proxies: tuple[Network, ...] = ()

    def trusted(self, addr: str) -> bool:
        return bool(self.proxies) and _in(addr, self.proxies)

    def of(self, scope: dict) -> str:
        peer = (scope.get("client") or ("",))[0]
        if self.header is None or not self.trusted(peer):
            return peer
        name = self.header.encode("latin-1")
        values = [v.decode("latin-1") for k, v in scope.get("headers", ()) if k.lower() == name]
        hops = [h.strip() for v in values for h in v.split(",")]
        for hop in reversed(hops):
            if _address(hop) is None:
                return peer  # a proxy that writes garbage is not believed further
            if not self.trusted(hop):
                return hop
        return peer


@lru_cache(maxsize=4096)
def _address(text: str) -> ipaddress.IPv4Address | ipaddress.IPv6Address | None:
    try:
        return ipaddress.ip_address(text)
    except ValueError:
        return None


def _in(addr: str, nets: tuple[Network, ...]) -> bool:
    ip = _address(addr)
    return ip is not None and any(ip in n for n in nets)
