"""Several worker processes behind one port, each with its own SO_REUSEPORT listening
socket, so that the kernel spreads new connections over the workers.

uvicorn's `--workers` shares one listening socket: an idle worker's event loop accepts every
queued connection at once, so keep-alive clients that connect together all land on one
worker (measured: 4 clients, 2 workers, every check served by one of them), and that socket
is made without proto=IPPROTO_TCP, so asyncio leaves Nagle on (+40 ms per response).
"""

from __future__ import annotations

import multiprocessing
import signal
import socket
import sys
import time
from typing import Any

#: a worker that dies sooner than this after its start is not restarted: the server stops
MIN_WORKER_LIFE_S = 10.0


def _listen_socket(host: str, port: int, listen: bool) -> socket.socket:
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM, socket.IPPROTO_TCP)  # asyncio then sets TCP_NODELAY
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
    sock.bind((host, port))
    if listen:
        sock.listen(2048)
    return sock


def _worker(host: str, port: int, config: dict[str, Any]) -> None:
    import uvicorn

    sock = _listen_socket(host, port, listen=True)
    uvicorn.Server(uvicorn.Config(**config)).run(sockets=[sock])


def run_workers(host: str, port: int, workers: int, config: dict[str, Any]) -> int:
    """Run `workers` uvicorn servers on host:port until SIGINT/SIGTERM; restart one that dies
    after running a while. Returns the exit code."""
    reserved = _listen_socket(host, port, listen=False)  # fails now if the port is taken; never accepts
    ctx = multiprocessing.get_context("spawn")
    stopping: list[int] = []

    def start() -> tuple[Any, float]:
        proc = ctx.Process(target=_worker, args=(host, port, config), daemon=False)
        proc.start()
        return proc, time.monotonic()

    previous = {sig: signal.signal(sig, lambda s, _f: stopping.append(s)) for sig in (signal.SIGINT, signal.SIGTERM)}
    procs = [start() for _ in range(workers)]
    code = 0
    try:
        while not stopping:
            time.sleep(0.2)
            for i, (proc, started) in enumerate(procs):
                if proc.is_alive():
                    continue
                if time.monotonic() - started < MIN_WORKER_LIFE_S:
                    print(f"error: worker {proc.pid} exited with {proc.exitcode} during start-up; stopping",
                          file=sys.stderr)
                    stopping.append(0)
                    code = 3
                    break
                print(f"worker {proc.pid} exited with {proc.exitcode}; starting another", file=sys.stderr)
                procs[i] = start()
    finally:
        for proc, _ in procs:
            if proc.is_alive():
                proc.terminate()
        for proc, _ in procs:
            proc.join(30)
        reserved.close()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return code
