"""Several worker processes behind one port, each with its own SO_REUSEPORT listening
socket, so that the kernel spreads new connections over the workers; workers that die with
their parent.

uvicorn's `--workers` shares one listening socket: an idle worker's event loop accepts every
queued connection at once, so keep-alive clients that connect together all land on one
worker (measured: 4 clients, 2 workers, every check served by one of them), and that socket
is made without proto=IPPROTO_TCP, so asyncio leaves Nagle on (+40 ms per response).
gunicorn's arbiter also hands one shared socket to every worker, and it does not stop its
uvicorn workers when it is killed: with gunicorn 27.0.1 and uvicorn-worker 0.4.0, `kill -9`
of the arbiter left both UvicornWorkers alive and serving 15 s later (their notify callback
never checks the parent pid, which only gunicorn's own sync/gthread/gevent loops do).

Here a worker stops when its parent goes, however it goes (a `kill -9` runs no clean-up in
the parent):

- on Linux the worker asks the kernel for SIGTERM when its parent dies
  (`prctl(PR_SET_PDEATHSIG)`), then checks that the parent did not die before it asked;
- every worker also polls its parent pid twice a second (any POSIX system), and sends
  itself SIGTERM when it changes;
- SIGTERM is uvicorn's graceful stop: the listening socket closes at once, requests in
  flight may finish; ORPHAN_GRACE_S later an orphan exits regardless.

Before any worker starts, the port is bound once *without* SO_REUSEPORT: that fails while
anything listens there, including another `authn serve` (whose SO_REUSEPORT sockets would
otherwise let the two share the port silently, as orphaned workers did after a restart).
"""

from __future__ import annotations

import errno
import multiprocessing
import os
import signal
import socket
import sys
import threading
import time
from typing import Any

from core.errors import SystemFault
from authn.process import tune
from authn.service.connections import ConnectionLimits

#: a worker that dies sooner than this after its start is not restarted: the server stops
MIN_WORKER_LIFE_S = 10.0
#: seconds an orphaned worker may spend finishing requests after its parent died
ORPHAN_GRACE_S = 5.0
#: how often a worker looks at its parent pid
PARENT_POLL_S = 0.5
PR_SET_PDEATHSIG = 1


def _family(host: str) -> socket.AddressFamily:
    return socket.AF_INET6 if ":" in host else socket.AF_INET


def _listen_socket(host: str, port: int, listen: bool) -> socket.socket:
    sock = socket.socket(_family(host), socket.SOCK_STREAM, socket.IPPROTO_TCP)  # asyncio then sets TCP_NODELAY
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
    sock.bind((host, port))
    if listen:
        sock.listen(2048)
    return sock


def _claim_port(host: str, port: int) -> socket.socket:
    """Fail clearly if anything holds host:port, then reserve it for our workers."""
    probe = socket.socket(_family(host), socket.SOCK_STREAM, socket.IPPROTO_TCP)
    probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # TIME_WAIT leftovers are no obstacle
    try:
        probe.bind((host, port))  # no SO_REUSEPORT: refused while any socket listens there
    except OSError as exc:
        if exc.errno == errno.EADDRINUSE:
            raise SystemFault(f"port {port} on {host} is in use (another server, or workers of an "
                              "authn serve that is still stopping)") from None
        raise SystemFault(f"cannot listen on {host}:{port}: {exc.strerror or exc}") from None
    finally:
        probe.close()
    return _listen_socket(host, port, listen=False)  # holds the port while workers come and go; never accepts


def _die_with_parent(parent: int) -> None:
    """SIGTERM this process when `parent` is gone: kernel (Linux), and a polling thread."""
    if sys.platform.startswith("linux"):
        import ctypes

        try:
            ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
        except (OSError, AttributeError):
            pass  # the polling thread below still covers it

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        print(f"worker {os.getpid()}: parent {parent} is gone; stopping", file=sys.stderr, flush=True)
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(ORPHAN_GRACE_S)
        os._exit(3)

    if os.getppid() != parent:  # died before we asked
        os._exit(3)
    threading.Thread(target=watch, name="authn-parent-watch", daemon=True).start()


def _raise_fd_limit() -> None:
    """Sockets are file descriptors: take the hard limit (the soft one is often 1024)."""
    try:
        import resource

        soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
        want = 65536 if hard == resource.RLIM_INFINITY else min(hard, 65536)
        if soft != resource.RLIM_INFINITY and soft < want:
            resource.setrlimit(resource.RLIMIT_NOFILE, (want, hard))
    except (ImportError, ValueError, OSError):
        pass


def _worker(host: str, port: int, config: dict[str, Any], limits: ConnectionLimits, parent: int) -> None:
    _die_with_parent(parent)
    _raise_fd_limit()
    tune()  # a spawned interpreter: the `authn` process's settings again
    import uvicorn

    from authn.service.connections import GuardedH11Protocol, configure

    configure(limits)
    sock = _listen_socket(host, port, listen=True)
    uvicorn.Server(uvicorn.Config(**config, http=GuardedH11Protocol, ws="none", limit_concurrency=None)
                   ).run(sockets=[sock])


def run_workers(host: str, port: int, workers: int, config: dict[str, Any],
                limits: ConnectionLimits | None = None) -> int:
    """Run `workers` uvicorn servers on host:port until SIGINT/SIGTERM; restart one that dies
    after running a while. Returns the exit code."""
    limits = limits or ConnectionLimits()
    reserved = _claim_port(host, port)
    ctx = multiprocessing.get_context("spawn")
    stopping: list[int] = []

    def start() -> tuple[Any, float]:
        proc = ctx.Process(target=_worker, args=(host, port, config, limits, os.getpid()), daemon=False)
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
