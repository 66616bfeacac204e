"""Raw-socket HTTP clients that behave as an attacker would against `authn serve`: a huge
body pushed as fast as the server takes it (how much did it take before it answered?), and
bodies that start and then stop (does the server cut them, and can others still get in?).
Shared by tests/service and benchmarks/serve_abuse.py."""

from __future__ import annotations

import select
import socket
import time
from dataclasses import dataclass

#: the client's send buffer while pushing: small, so bytes the kernel accepted are close to
#: bytes the server read (the server's receive buffer still holds some)
SEND_BUFFER = 64 * 1024


@dataclass(frozen=True)
class Pushed:
    status: int | None  # None: no reply before the connection ended or the time ran out
    sent: int  # body bytes the socket accepted before the reply (or the end)
    seconds: float
    reply: bytes


def _connect(host: str, port: int, source: str, timeout_s: float = 10.0) -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SEND_BUFFER)
    sock.settimeout(timeout_s)
    sock.bind((source, 0))
    sock.connect((host, port))
    return sock


def _head(method: str, path: str, host: str, headers: dict[str, str]) -> bytes:
    lines = [f"{method} {path} HTTP/1.1", f"Host: {host}", *(f"{k}: {v}" for k, v in headers.items())]
    return ("\r\n".join(lines) + "\r\n\r\n").encode()


def _status(reply: bytes) -> int | None:
    first = reply.split(b"\r\n", 1)[0].split()
    return int(first[1]) if len(first) >= 2 and first[1].isdigit() else None


def _complete(reply: bytes) -> bool:
    """The reply's head and as much body as its Content-Length says are in."""
    head, sep, body = reply.partition(b"\r\n\r\n")
    if not sep:
        return False
    for line in head.split(b"\r\n")[1:]:
        name, _, value = line.partition(b":")
        if name.strip().lower() == b"content-length" and value.strip().isdigit():
            return len(body) >= int(value)
    return True


def push_body(host: str, port: int, path: str, headers: dict[str, str], total: int, chunked: bool = True,
              prefix: bytes = b"", source: str = "127.0.0.1", timeout_s: float = 30.0) -> Pushed:
    """POST a body of `total` bytes (`prefix`, e.g. a multipart part's head, then filler;
    chunked, or with that Content-Length), sending as fast as the socket accepts it, until the
    server replies or closes: what it answered, how many body bytes it had taken by then
    (reply in), and when."""
    headers = {**headers, **({"Transfer-Encoding": "chunked"} if chunked else {"Content-Length": str(total)})}
    sock = _connect(host, port, source)
    t0 = time.monotonic()
    payload = b"x" * 65536

    def piece(data: bytes) -> bytes:
        return f"{len(data):x}\r\n".encode() + data + b"\r\n" if chunked else data

    sent, reply, answered, ended = 0, b"", None, False
    pending = piece(prefix) if prefix else b""
    try:
        sock.sendall(_head("POST", path, f"{host}:{port}", headers))
        sock.setblocking(False)
        while time.monotonic() - t0 < timeout_s:
            want_write = not ended or pending
            readable, writable, _ = select.select([sock], [sock] if want_write else [], [], 0.5)
            if readable:
                data = sock.recv(65536)
                if not data:
                    break
                reply += data
                if answered is None and b"\r\n" in reply:
                    answered = sent  # what the server had taken when it answered
                if _complete(reply):
                    break
            if writable:
                if not pending:
                    if sent < total:
                        pending = piece(payload[:total - sent])
                    else:
                        pending, ended = (b"0\r\n\r\n" if chunked else b""), True
                    if not pending:
                        continue
                n = sock.send(pending)
                sent += n
                pending = pending[n:]
    except (ConnectionResetError, BrokenPipeError):
        # the server answered and closed with our bytes unread (a reset): its reply may still sit
        # in our receive queue, unread because the send failed first; the kernel hands it over
        # before the reset's error
        reply += _drain(sock)
        if answered is None and b"\r\n" in reply:
            answered = sent
    finally:
        sock.close()
    return Pushed(_status(reply), sent if answered is None else answered, time.monotonic() - t0, reply)


def _drain(sock: socket.socket) -> bytes:
    """What can still be read from a socket the peer has reset."""
    got = b""
    try:
        while True:
            data = sock.recv(65536)
            if not data:
                return got
            got += data
    except OSError:  # the reset's own error (or nothing queued: EAGAIN), after the queued bytes
        return got


def start_slow_body(host: str, port: int, path: str, headers: dict[str, str], first: bytes = b"--b\r\n",
                    declared: int = 100_000, source: str = "127.0.0.1") -> socket.socket:
    """A request whose body starts (`first`) and then stops: the server holds it until its
    body timeout."""
    sock = _connect(host, port, source)
    sock.sendall(_head("POST", path, f"{host}:{port}", {**headers, "Content-Length": str(declared)}) + first)
    return sock


def read_reply(sock: socket.socket, timeout_s: float) -> tuple[int | None, float, bytes]:
    """(status, seconds waited, bytes) of the server's reply on `sock`: None if it sent none."""
    t0 = time.monotonic()
    sock.settimeout(timeout_s)
    reply = b""
    try:
        while data := sock.recv(65536):
            reply += data
    except (TimeoutError, ConnectionResetError):
        pass
    return _status(reply), time.monotonic() - t0, reply
