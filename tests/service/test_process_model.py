"""`authn serve` workers die with their parent (authn/service/workers.py): after a `kill -9`
of the parent no worker is left serving, the port is free, and a server started again on it
answers every request from its own workers (orphans used to answer 21 of 40)."""

from __future__ import annotations

import os
import signal
import socket
import sys
import time
from pathlib import Path

import httpx
import pytest

from tests.service.server import alive, children, server_env, start

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")


def _workers(pid: int) -> list[int]:
    """The spawned worker processes of `authn serve` `pid` (not multiprocessing's resource tracker)."""
    found = []
    for child in children(pid):
        try:
            cmd = Path(f"/proc/{child}/cmdline").read_bytes()
        except OSError:
            continue
        if b"spawn_main" in cmd:
            found.append(child)
    return found


def test_kill_9_of_the_parent_leaves_no_worker(sqlite_db, keys_dir, tmp_path) -> None:
    env = server_env(keys_dir)
    srv = start(sqlite_db, tmp_path / "a.log", env, "--workers", "2")
    port = int(srv.url.rsplit(":", 1)[1])
    descendants: list[int] = []
    try:
        workers = _workers(srv.proc.pid)
        descendants = children(srv.proc.pid)  # the workers and multiprocessing's resource tracker
        answered = {httpx.get(f"{srv.url}/healthz", headers={"Connection": "close"}, timeout=10).json()["worker"]
                    for _ in range(20)}
        assert len(workers) == 2 and answered <= set(workers), (workers, answered)
        t0 = time.monotonic()
        os.kill(srv.proc.pid, signal.SIGKILL)
        srv.proc.wait(10)
        while any(alive(p) for p in descendants) and time.monotonic() - t0 < 15:
            time.sleep(0.05)
        gone_s = time.monotonic() - t0
        left = [p for p in descendants if alive(p)]
    finally:
        for p in children(srv.proc.pid) + [p for p in descendants if alive(p)]:
            try:
                os.kill(p, signal.SIGKILL)  # only if the test failed: leave nothing behind
            except ProcessLookupError:
                pass
    log = srv.log.read_text()
    print(f"kill -9 of the parent: {len(descendants)} child processes gone after {gone_s:.2f} s")
    assert not left, f"still running {gone_s:.1f} s after kill -9 of the parent: {left}\n{log[-2000:]}"
    assert gone_s < 10.0, gone_s
    assert "Traceback" not in log
    with pytest.raises(httpx.ConnectError):
        httpx.get(f"{srv.url}/healthz", timeout=2)
    with socket.socket() as s:  # free: bound without SO_REUSEPORT, as the next server's check does
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.bind(("127.0.0.1", port))

    again = start(sqlite_db, tmp_path / "b.log", env, "--workers", "2", port=port)
    try:
        mine = set(_workers(again.proc.pid))
        answered = [httpx.get(f"{again.url}/healthz", headers={"Connection": "close"}, timeout=10).json()["worker"]
                    for _ in range(40)]
    finally:
        log = again.stop()
    assert set(answered) <= mine, (answered, mine)
    assert again.proc.returncode == 0 and "Traceback" not in log
