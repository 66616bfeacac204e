"""`authn serve` against the attacks of issue 55, at full scale: huge bodies without a key, and
slow bodies from a few addresses while another address checks.

    python benchmarks/serve_abuse.py [--workers 2] [--push-mib 1024] [--addresses 8] [--per-address 70]
                                     [--checks 20] [--hold-s 20] [--no-key-slow] [--serve-args "..."]

1. Starts `authn serve --workers N` on a fresh SQLite database in a temporary folder.
2. Bodies: on every POST endpoint, a --push-mib body (chunked, then with a declared
   Content-Length) without a key, with a bad key, with an operator key on the admin endpoints,
   and with an admin key; for each, the status, the body bytes the socket had accepted when
   the reply came, and the seconds to the reply.
3. Slow bodies: --per-address check uploads from each of --addresses loopback addresses
   (127.0.0.2 ...) that send a part head and then nothing, with a valid operator key (or none,
   --no-key-slow); every one the server closes is opened again each 0.5 s. After --hold-s / 4
   seconds, --checks real checks from the next address, each on a new connection: how many
   answered 200, p50 and p99, and the workers' /readyz load.

Prints one JSON document; exit 1 unless every body was answered 401/403/413 within 1 s having
taken < 1 MiB (413: twice the limit + 1 MiB, as the server's kernel receive buffer grows while
it reads up to the limit) and >= checks - 1 real checks answered 200. Linux (the whole of
127.0.0.0/8 is loopback there).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import selectors
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from lab.http_abuse import push_body, start_slow_body  # noqa: E402

MiB = 2**20
M300 = "1581BDEM00000002"
UPLOADS = {"/v1/checks": "file", "/v1/checks:batch": "files", "/v1/checks:track": "files"}
ADMIN = ("/v1/audit:checkpoint", "/v1/identities", f"/v1/identities/{M300}:revoke")


def _prefix(path: str) -> tuple[dict[str, str], bytes]:
    if path in UPLOADS:
        return ({"Content-Type": "multipart/form-data; boundary=b"},
                (f'--b\r\nContent-Disposition: form-data; name="{UPLOADS[path]}"; filename="a.h5"\r\n'
                 "Content-Type: application/octet-stream\r\n\r\n").encode())
    return {"Content-Type": "application/json"}, b'{"serial": "'


def _start(db: str, workers: int, port: int, log: Path, extra: list[str]) -> subprocess.Popen:
    import httpx

    proc = subprocess.Popen([sys.executable, "-m", "authn", "--db", db, "serve", "--port", str(port),
                             "--workers", str(workers), *extra], stdout=log.open("w"), stderr=subprocess.STDOUT,
                            cwd=ROOT)
    t0 = time.monotonic()
    while time.monotonic() - t0 < 60:
        if proc.poll() is not None:
            raise SystemExit(f"authn serve exited: {log.read_text()[-2000:]}")
        try:
            if httpx.get(f"http://127.0.0.1:{port}/readyz", timeout=1).status_code == 200:
                return proc
        except httpx.TransportError:
            pass
        time.sleep(0.05)
    proc.kill()
    raise SystemExit("authn serve not ready after 60 s")


def _bodies(port: int, tokens: dict[str, str], push: int, upload_limit: int) -> list[dict]:
    """Every POST endpoint, every kind of caller, a body of `push` bytes chunked and declared."""
    rows = []
    for path in [*UPLOADS, *ADMIN]:
        headers, prefix = _prefix(path)
        callers = {"none": None, "bad key": "authn_nope", "admin": tokens["admin"]}
        if path in ADMIN:
            callers["operator"] = tokens["operator"]
        for who, token in callers.items():
            auth = {"Authorization": f"Bearer {token}"} if token else {}
            for chunked in (True, False):
                got = push_body("127.0.0.1", port, path, {**headers, **auth}, push, chunked=chunked, prefix=prefix)
                limit = upload_limit if path in UPLOADS else 64 * 1024
                # the count includes the server's kernel receive buffer, which grows while it reads
                ok = (got.status in (401, 403, 413) and got.seconds < 1.0
                      and got.sent < (2 * limit + MiB if got.status == 413 else MiB))
                rows.append({"path": path, "caller": who, "chunked": chunked, "status": got.status,
                             "taken_bytes": got.sent, "seconds": round(got.seconds, 3), "ok": ok})
    return rows


class SlowBodies:
    """--per-address slow check uploads from each address, reopened when the server closes one."""

    def __init__(self, port: int, addresses: list[str], per_address: int, token: str | None) -> None:
        self.port, self.addresses, self.per_address = port, addresses, per_address
        self.headers = {**_prefix("/v1/checks")[0], **({"Authorization": f"Bearer {token}"} if token else {})}
        self.prefix = _prefix("/v1/checks")[1]
        self.sel = selectors.DefaultSelector()
        self.open = {a: 0 for a in addresses}
        self.stats = {"opened": 0, "closed_by_server": 0, "connect_failed": 0}
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _connect(self, addr: str) -> None:
        try:
            sock = start_slow_body("127.0.0.1", self.port, "/v1/checks", self.headers, self.prefix, source=addr)
        except OSError:
            self.stats["connect_failed"] += 1
            return
        sock.setblocking(False)
        self.sel.register(sock, selectors.EVENT_READ, addr)
        self.open[addr] += 1
        self.stats["opened"] += 1

    def _run(self) -> None:
        while not self.stop.is_set():
            for addr in self.addresses:
                for _ in range(self.per_address - self.open[addr]):
                    self._connect(addr)
            deadline = time.monotonic() + 0.5
            while (left := deadline - time.monotonic()) > 0:
                for key, _ in self.sel.select(left):
                    try:
                        key.fileobj.recv(65536)  # a reply (408/413/503) or the close: either way it is gone
                    except OSError:
                        pass
                    self.sel.unregister(key.fileobj)
                    key.fileobj.close()
                    self.open[key.data] -= 1
                    self.stats["closed_by_server"] += 1
        for key in list(self.sel.get_map().values()):
            key.fileobj.close()


def _checks(port: int, token: str, source: str, n: int, body: bytes) -> tuple[list[int | str], list[float]]:
    import httpx

    statuses: list[int | str] = []
    took = []
    for _ in range(n):
        t0 = time.monotonic()
        try:
            with httpx.Client(transport=httpx.HTTPTransport(local_address=source), timeout=60) as c:
                resp = c.post(f"http://127.0.0.1:{port}/v1/checks", headers={"Authorization": f"Bearer {token}"},
                              files={"file": ("g.h5", body, "application/x-hdf5")})
            statuses.append(resp.status_code)
        except httpx.TransportError as exc:
            statuses.append(type(exc).__name__)
        took.append(time.monotonic() - t0)
    return statuses, took


def _loads(port: int, n: int = 8) -> list[dict]:
    import httpx

    seen: dict[int, dict] = {}
    for _ in range(n):  # a new connection each: the kernel picks a worker
        try:
            load = httpx.get(f"http://127.0.0.1:{port}/readyz", timeout=10).json()["load"]
            seen[load["worker"]] = {k: load.get(k) for k in ("in_flight", "receiving_body", "busy", "preempted")}
        except Exception:  # noqa: BLE001 - a probe that fails is reported as missing
            continue
    return list(seen.values())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--port", type=int, default=8766)
    ap.add_argument("--push-mib", type=int, default=1024)
    ap.add_argument("--addresses", type=int, default=8)
    ap.add_argument("--per-address", type=int, default=70)
    ap.add_argument("--checks", type=int, default=20)
    ap.add_argument("--hold-s", type=float, default=20.0, help="how long the slow bodies are held")
    ap.add_argument("--no-key-slow", action="store_true", help="slow bodies without a key (401 at once)")
    ap.add_argument("--serve-args", default="", help="more `authn serve` options")
    args = ap.parse_args()
    _, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (min(hard, 65536) if hard != resource.RLIM_INFINITY else 65536, hard))
    tmp = Path(tempfile.mkdtemp(prefix="authn-serve-abuse-"))
    os.environ.update({"AUTHN_LOG_KEY": str(tmp / "log.pem"), "AUTHN_AUDIT_STH_LOG": str(tmp / "sth.jsonl"),
                       "AUTHN_SERVE_FIGURES_DIR": str(tmp / "figures")})
    from authn.demo import register_examples
    from authn.service.keys import create_key
    from authn.scenario import Broadcast, simulate_flight
    from signatures.profiles import shipped_profiles
    from signatures.radar import get_preset
    from signatures.recording import write_recording
    from signatures.sim.scene import Scene

    db = f"sqlite:///{tmp / 'authn.sqlite3'}"
    register_examples(db)
    tokens = {role: create_key(db, role, f"abuse-{role}")[1] for role in ("admin", "operator")}
    sc = Scene(kind="uav", profile=shipped_profiles().get("m300"), snr_db=20.0, range_m=400.0,
               radial_speed_mps=3.0, elevation_deg=10.0)
    rec, _ = simulate_flight(sc, get_preset("paper"), 11, Broadcast(serial=M300), azimuth_deg=60.0)
    body = write_recording(rec, tmp / "genuine.h5").read_bytes()
    proc = _start(db, args.workers, args.port, tmp / "serve.log", args.serve_args.split())
    summary: dict = {"workers": args.workers, "cpus": os.cpu_count()}
    try:
        rows = _bodies(args.port, tokens, args.push_mib * MiB, 64 * MiB + 64 * 1024)
        summary["bodies"] = {"pushed_mib": args.push_mib, "answered_ok": sum(r["ok"] for r in rows),
                             "of": len(rows), "max_taken_bytes": max(r["taken_bytes"] for r in rows),
                             "max_seconds": max(r["seconds"] for r in rows), "rows": rows}
        sources = [f"127.0.0.{2 + i}" for i in range(args.addresses)]
        slow = SlowBodies(args.port, sources, args.per_address, None if args.no_key_slow else tokens["operator"])
        slow.thread.start()
        time.sleep(args.hold_s / 4)
        held = _loads(args.port)
        statuses, took = _checks(args.port, tokens["operator"], f"127.0.0.{2 + args.addresses}", args.checks, body)
        time.sleep(max(0.0, args.hold_s / 4))
        slow.stop.set()
        slow.thread.join(30)
        summary["slow_bodies"] = {"addresses": args.addresses, "per_address": args.per_address,
                                  "with_key": not args.no_key_slow, "loads_while_held": held, **slow.stats,
                                  "checks_200": statuses.count(200), "checks": len(statuses),
                                  "statuses": statuses, "p50_ms": round(float(np.median(took)) * 1e3),
                                  "p99_ms": round(float(np.percentile(took, 99)) * 1e3)}
    finally:
        proc.terminate()
        proc.wait(30)
    print(json.dumps(summary, indent=1))
    ok = summary["bodies"]["answered_ok"] == len(rows) and statuses.count(200) >= args.checks - 1
    raise SystemExit(0 if ok else 1)


if __name__ == "__main__":
    main()
