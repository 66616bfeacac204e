"""Nothing answered is lost: checks served while the whole service is killed (kill -9 of the
parent, its workers then stop) each have their audit entry, and the log verifies."""

from __future__ import annotations

import os
import signal
import threading
import time
from pathlib import Path

import httpx

from tests.service.conftest import make_keys
from tests.service.server import M300, server_env, start


def test_every_answered_check_is_audited_across_a_kill_9(tmp_path: Path, keys_dir: Path, returns) -> None:
    from authn.audit import get_entry, verify
    from authn.demo import register_examples
    from registry.dbapi import Database

    db_url = f"sqlite:///{tmp_path / 'authn.sqlite3'}"
    register_examples(db_url)
    token = make_keys(db_url).operator
    srv = start(db_url, tmp_path / "serve.log", server_env(keys_dir), "--workers", "2")
    data = returns["genuine"].read_bytes()
    answered: list[tuple[int, str]] = []
    stop = threading.Event()

    def client() -> None:
        with httpx.Client(base_url=srv.url, headers={"Authorization": f"Bearer {token}"}, timeout=30.0) as c:
            while not stop.is_set():
                try:
                    r = c.post("/v1/checks", files={"file": ("g.h5", data)}, data={"serial": M300})
                except httpx.TransportError:
                    return  # the service is gone
                if r.status_code == 200:
                    doc = r.json()
                    answered.append((doc["audit_id"], doc["decision"]))

    threads = [threading.Thread(target=client) for _ in range(3)]
    for t in threads:
        t.start()
    try:
        deadline = time.monotonic() + 30
        while len(answered) < 30 and time.monotonic() < deadline:
            time.sleep(0.05)
        os.kill(srv.proc.pid, signal.SIGKILL)  # the whole service: its workers follow it
        srv.proc.wait(10)
        for t in threads:
            t.join(30)
    finally:
        stop.set()
    assert len(answered) >= 30, f"only {len(answered)} checks answered before the kill"
    db = Database(db_url)
    try:
        for seq, decision in answered:
            entry = get_entry(db, seq)
            assert entry is not None and entry.decision == decision, f"answered check {seq} not in the audit log"
        assert verify(db).ok
    finally:
        db.close()
