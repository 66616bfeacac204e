"""`authn serve` under load: checks/s sustained, p50/p99, and the audit chain after
concurrent clients.

    python benchmarks/locust_serve.py [--db URL --db2 URL] [--workers 2] [--users 2] [--duration 60]
                                      [--connection close|keep-alive] [--clients 4] [--checks-each 250]
                                      [--idle-flood 600 [--flood-reopen]] [--serve-args "..."]

1. Simulates paper-preset returns (genuine and spoofed claims), starts `authn serve
   --workers N` on a fresh database (SQLite in a temporary folder, or --db, which must be
   empty: give a fresh PostgreSQL database) and times start-up to /readyz green.
2. Runs locust headless in this process (--users closed-loop clients, no think time) for
   --duration seconds after a 5 s warm-up: checks/s, p50, p99, failures.
   With --idle-flood N, N TCP connections that never send a byte are held open to the
   server during the load phase (tests/service/flood.py, a separate process; with
   --flood-reopen every one the server closes is opened again each 0.5 s).
3. On a second fresh database, --clients threads post --checks-each returns each, then
   `authn audit verify` must pass with exactly clients x checks-each entries.

As a locustfile against a server already running (token and a folder of returns in the
environment): AUTHN_BENCH_TOKEN=... AUTHN_BENCH_RETURNS=dir locust -f benchmarks/locust_serve.py
--headless -u 4 -r 4 -t 60s --host http://127.0.0.1:8080
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from locust import HttpUser, constant, task

ROOT = Path(__file__).resolve().parents[1]
M600, M300 = "1581BDEM00000001", "1581BDEM00000002"


class CheckUser(HttpUser):
    """One radar client: posts returns back to back."""

    wait_time = constant(0)
    token = os.environ.get("AUTHN_BENCH_TOKEN", "")
    files: list[tuple[str, bytes]] = []
    boundary = "authnbenchboundary"

    def on_start(self) -> None:
        if not CheckUser.files and os.environ.get("AUTHN_BENCH_RETURNS"):
            returns = sorted(Path(os.environ["AUTHN_BENCH_RETURNS"]).glob("*.h5"))
            CheckUser.files = [(p.name, p.read_bytes()) for p in returns]
        # the multipart bodies are built once: the client's CPU is the server's on a 2-core box
        self.bodies = itertools.cycle([self._multipart(name, data) for name, data in CheckUser.files])
        self.headers = {"Authorization": f"Bearer {self.token}",
                        "Content-Type": f"multipart/form-data; boundary={self.boundary}"}
        if os.environ.get("AUTHN_BENCH_CONNECTION") == "close":  # a new connection per check
            self.headers["Connection"] = "close"

    def _multipart(self, name: str, data: bytes) -> bytes:
        return (f"--{self.boundary}\r\nContent-Disposition: form-data; name=\"file\"; filename=\"{name}\"\r\n"
                "Content-Type: application/x-hdf5\r\n\r\n").encode() + data + f"\r\n--{self.boundary}--\r\n".encode()

    @task
    def check(self) -> None:
        with self.client.post("/v1/checks", data=next(self.bodies), name="/v1/checks", catch_response=True,
                              headers=self.headers) as resp:
            if resp.status_code != 200:
                resp.failure(f"status {resp.status_code}: {resp.text[:200]}")


def _returns(out: Path, n: int) -> list[Path]:
    """Paper-preset returns: genuine M300 and M600 claims and a type spoof, several seeds."""
    from datetime import datetime, timezone

    from authn.scenario import Broadcast, simulate_flight
    from signatures.profiles import shipped_profiles
    from signatures.radar import get_preset
    from signatures.recording import write_recording
    from signatures.sim.scene import Scene

    kinds = [("m300", M300), ("m600", M600), ("phantom4", M600)]
    paths = []
    for i in range(n):
        flies, serial = kinds[i % len(kinds)]
        sc = Scene(kind="uav", profile=shipped_profiles().get(flies), snr_db=20.0, range_m=300.0 + 20 * i,
                   radial_speed_mps=3.0, elevation_deg=10.0)
        rec, _ = simulate_flight(sc, get_preset("paper"), 100 + i, Broadcast(serial=serial), azimuth_deg=60.0,
                                 start_time=datetime.now(timezone.utc))
        paths.append(write_recording(rec, out / f"{i:02d}-{flies}.h5"))
    return paths


def _fresh_db(base: str | None, tmp: Path, name: str) -> str:
    from authn.demo import register_examples

    url = base or f"sqlite:///{tmp / f'{name}.sqlite3'}"
    register_examples(url)
    return url


def _start(db_url: str, workers: int, port: int, log: Path, extra: list[str] = ()) -> tuple[subprocess.Popen, float]:
    import httpx

    t0 = time.monotonic()
    proc = subprocess.Popen([sys.executable, "-m", "authn", "--db", db_url, "serve", "--port", str(port),
                             "--workers", str(workers), *extra], stdout=log.open("w"), stderr=subprocess.STDOUT)
    while time.monotonic() - t0 < 60:
        if proc.poll() is not None:
            raise SystemExit(f"authn serve exited: {log.read_text()[-2000:]}")
        try:
            if httpx.get(f"http://127.0.0.1:{port}/readyz", timeout=1).status_code == 200:
                return proc, time.monotonic() - t0
        except httpx.TransportError:
            pass
        time.sleep(0.02)
    proc.kill()
    raise SystemExit("authn serve not ready after 60 s")


def _stop(proc: subprocess.Popen) -> None:
    proc.terminate()
    proc.wait(30)


def _flood(port: int, n: int, reopen: bool, duration: float) -> subprocess.Popen:
    """N idle connections held open in another process (tests/service/flood.py)."""
    proc = subprocess.Popen([sys.executable, "-m", "tests.service.flood", "--port", str(port), "--n", str(n),
                             "--duration", str(duration), *(["--reopen"] if reopen else [])], cwd=ROOT,
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    first = proc.stdout.readline()
    if json.loads(first or "{}").get("open") != n:
        raise SystemExit(f"idle flood did not open {n} connections: {first!r}")
    return proc


def _flood_stop(proc: subprocess.Popen) -> dict:
    proc.stdin.close()
    out = proc.stdout.read()
    proc.wait(30)
    return json.loads(out.strip().splitlines()[-1])


def _locust(url: str, token: str, files: list[Path], users: int, duration: float) -> dict:
    import gevent
    from locust.env import Environment

    CheckUser.token = token
    CheckUser.files = [(p.name, p.read_bytes()) for p in files]
    env = Environment(user_classes=[CheckUser], host=url)
    runner = env.create_local_runner()
    runner.start(users, spawn_rate=users)
    gevent.sleep(5)  # warm-up, not counted
    env.stats.reset_all()
    t0 = time.monotonic()
    gevent.sleep(duration)
    elapsed = time.monotonic() - t0
    s = env.stats.total
    result = {"users": users, "duration_s": round(elapsed, 1), "checks": s.num_requests,
              "failures": s.num_failures, "checks_per_s": round(s.num_requests / elapsed, 1),
              "p50_ms": s.get_response_time_percentile(0.5), "p99_ms": s.get_response_time_percentile(0.99)}
    runner.quit()
    return result


def _clients(url: str, token: str, files: list[Path], clients: int, each: int) -> list[int]:
    import httpx

    bodies = [(p.name, p.read_bytes()) for p in files]

    def client(i: int) -> list[int]:
        with httpx.Client(base_url=url, headers={"Authorization": f"Bearer {token}"}, timeout=60) as c:
            return [c.post("/v1/checks", files={"file": (n, b, "application/x-hdf5")}).status_code
                    for n, b in itertools.islice(itertools.cycle(bodies[i:] + bodies[:i]), each)]

    with ThreadPoolExecutor(clients) as pool:
        return [s for part in pool.map(client, range(clients)) for s in part]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--db", default=None, help="empty database URL (default: SQLite files in a temporary folder); "
                                              "the load phase and the chain phase each need their own")
    ap.add_argument("--db2", default=None, help="second empty database for the 4 x 250 phase (with --db)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--users", type=int, default=2)
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--clients", type=int, default=4)
    ap.add_argument("--checks-each", type=int, default=250)
    ap.add_argument("--returns", type=int, default=12)
    ap.add_argument("--port", type=int, default=8765)
    ap.add_argument("--idle-flood", type=int, default=0, metavar="N",
                    help="hold N idle TCP connections to the server during the load phase")
    ap.add_argument("--flood-reopen", action="store_true", help="reopen the idle connections the server closes")
    ap.add_argument("--serve-args", default="", help="more `authn serve` options, e.g. \"--header-timeout-s 2\"")
    ap.add_argument("--connection", choices=("close", "keep-alive"), default="close",
                    help="a new connection per check (radars posting dwells; the kernel spreads them over the "
                         "workers) or one kept-alive connection per user (each stays on one worker)")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="authn-serve-bench-"))
    os.environ.setdefault("AUTHN_LOG_KEY", str(tmp / "log.pem"))
    os.environ.setdefault("AUTHN_AUDIT_STH_LOG", str(tmp / "sth.jsonl"))
    from authn.cli import main as cli
    from authn.service.keys import create_key

    os.environ["AUTHN_BENCH_CONNECTION"] = args.connection
    files = _returns(tmp, args.returns)
    url = f"http://127.0.0.1:{args.port}"
    summary: dict = {"workers": args.workers, "cpus": os.cpu_count(), "connection": args.connection,
                     "database": "postgresql" if args.db and args.db.startswith("postgresql") else "sqlite"}

    db = _fresh_db(args.db, tmp, "load")
    token = create_key(db, "operator", "bench")[1]
    extra = args.serve_args.split()
    proc, ready_s = _start(db, args.workers, args.port, tmp / "serve-load.log", extra)
    summary["readyz_s"] = round(ready_s, 2)
    flood = None
    try:
        if args.idle_flood:
            flood = _flood(args.port, args.idle_flood, args.flood_reopen, args.duration + 60)
        summary["load"] = _locust(url, token, files, args.users, args.duration)
    finally:
        if flood is not None:
            summary["idle_flood"] = {"connections": args.idle_flood, "reopen": args.flood_reopen, **_flood_stop(flood)}
            summary["idle_flood"].pop("final", None)
        _stop(proc)

    db2 = _fresh_db(args.db2 if args.db else None, tmp, "chain")
    token = create_key(db2, "operator", "bench")[1]
    proc, _ = _start(db2, args.workers, args.port, tmp / "serve-chain.log", extra)
    try:
        t0 = time.monotonic()
        statuses = _clients(url, token, files, args.clients, args.checks_each)
        wall = time.monotonic() - t0
    finally:
        _stop(proc)
    from registry.dbapi import Database

    entries = int(Database(db2).fetch("SELECT COUNT(*) FROM audit_log")[0][0])
    verify_code = cli(["--db", db2, "audit", "verify"])
    summary["chain"] = {"clients": args.clients, "checks_each": args.checks_each,
                        "ok_responses": statuses.count(200), "entries": entries,
                        "expected": args.clients * args.checks_each, "audit_verify_exit": verify_code,
                        "checks_per_s": round(len(statuses) / wall, 1)}
    print(json.dumps(summary, indent=2))
    if verify_code != 0 or entries != args.clients * args.checks_each or summary["load"]["failures"]:
        raise SystemExit(1)


if __name__ == "__main__":
    main()
