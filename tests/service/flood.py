"""Hold N TCP connections to a server open without ever sending a byte, as the idle-socket
attack on `authn serve` did; with --reopen, a connection the server closes is opened again at
the next sweep, so the server faces N idle sockets all the time.

    python -m tests.service.flood --port 8080 --n 600 --reopen --duration 30

Prints `{"open": N}` once all are connected, then one JSON line per second (open now, opened
in all, closed by the server in all), and a last line when --duration is over or stdin closes.
Used by tests/service/test_connection_limits.py and benchmarks/locust_serve.py --idle-flood.
"""

from __future__ import annotations

import argparse
import json
import selectors
import socket
import sys
import threading
import time


def _raise_fd_limit(need: int) -> None:
    import resource

    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft != resource.RLIM_INFINITY and soft < need:
        resource.setrlimit(resource.RLIMIT_NOFILE, (need if hard == resource.RLIM_INFINITY else min(need, hard), hard))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--n", type=int, default=600)
    ap.add_argument("--reopen", action="store_true", help="open again the connections the server closes")
    ap.add_argument("--sweep-s", type=float, default=0.5, help="how often closed connections are reopened")
    ap.add_argument("--duration", type=float, default=60.0)
    args = ap.parse_args(argv)
    _raise_fd_limit(args.n + 100)
    sel = selectors.DefaultSelector()  # epoll: select() stops at fd 1024
    stats = {"open": 0, "opened": 0, "closed_by_server": 0, "connect_failed": 0}

    def connect() -> None:
        try:
            s = socket.create_connection((args.host, args.port), timeout=5)
        except OSError:
            stats["connect_failed"] += 1
            return
        s.setblocking(False)
        sel.register(s, selectors.EVENT_READ)
        stats["opened"] += 1
        stats["open"] += 1

    stop = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), stop.set()), daemon=True).start()
    for _ in range(args.n):
        connect()
    print(json.dumps({"open": stats["open"]}), flush=True)
    t_end = time.monotonic() + args.duration
    next_report = time.monotonic() + 1.0
    while not stop.is_set() and time.monotonic() < t_end:
        deadline = time.monotonic() + args.sweep_s
        while (left := deadline - time.monotonic()) > 0:
            for key, _ in sel.select(left):
                s = key.fileobj
                try:
                    data = s.recv(4096)
                except (BlockingIOError, InterruptedError):
                    continue
                except OSError:
                    data = b""
                if not data:  # closed (a 408 is read first, then the close)
                    sel.unregister(s)
                    s.close()
                    stats["open"] -= 1
                    stats["closed_by_server"] += 1
        if args.reopen:
            for _ in range(args.n - stats["open"]):
                connect()
        if time.monotonic() >= next_report:
            print(json.dumps(stats), flush=True)
            next_report += 1.0
    print(json.dumps({"final": True, **stats}), flush=True)


if __name__ == "__main__":
    main()
