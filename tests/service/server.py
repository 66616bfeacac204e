"""A real `authn serve` in a subprocess on a free port, and the returns the tests upload."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import httpx

M600, M300 = "1581BDEM00000001", "1581BDEM00000002"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@dataclass
class Server:
    url: str
    proc: subprocess.Popen
    log: Path
    ready_s: float

    def client(self, token: str | None = None, **kw) -> httpx.Client:
        headers = {"Authorization": f"Bearer {token}"} if token else {}
        return httpx.Client(base_url=self.url, headers=headers, timeout=60.0, **kw)

    def stop(self) -> str:
        """Stop it (SIGTERM, as an operator would) and return its log."""
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(20)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        return self.log.read_text()


def server_env(keys_dir: Path) -> dict[str, str]:
    """The environment of a server: the tests' log key and STH log, no user model bundles."""
    models = keys_dir / "no-user-models"
    models.mkdir(parents=True, exist_ok=True)
    return {**os.environ, "AUTHN_LOG_KEY": str(keys_dir / "audit-log-key.pem"),
            "AUTHN_AUDIT_STH_LOG": str(keys_dir / "audit-sth.jsonl"), "AUTHN_MODELS_DIR": str(models)}


def start(db_url: str, log: Path, env: dict[str, str], *extra: str, timeout_s: float = 60.0,
          port: int | None = None) -> Server:
    """Start `authn serve` and wait until /readyz is green; `ready_s` is how long that took."""
    port = port or free_port()
    url = f"http://127.0.0.1:{port}"
    fh = log.open("w")
    t0 = time.monotonic()
    proc = subprocess.Popen([sys.executable, "-m", "authn", "--db", db_url, "serve", "--port", str(port), *extra],
                            stdout=fh, stderr=subprocess.STDOUT, env=env)
    server = Server(url, proc, log, 0.0)
    while time.monotonic() - t0 < timeout_s:
        if proc.poll() is not None:
            raise RuntimeError(f"authn serve exited with {proc.returncode}: {log.read_text()[-2000:]}")
        try:
            if httpx.get(f"{url}/readyz", timeout=1.0).status_code == 200:
                server.ready_s = time.monotonic() - t0
                return server
        except httpx.TransportError:
            pass
        time.sleep(0.05)
    server.stop()
    raise RuntimeError(f"authn serve not ready after {timeout_s} s: {log.read_text()[-2000:]}")


def children(pid: int) -> list[int]:
    """The process ids whose parent is `pid` (a /proc scan; Linux)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
            found.append(int(entry.name))
    return found


def alive(pid: int) -> bool:
    """Running (a zombie waiting to be reaped is not)."""
    try:
        return (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def flight(out: Path, name: str, flies: str, serial: str | None, offset: float = 0.0, seed: int = 11) -> Path:
    """A simulated paper-preset return (as tests/decision/test_check_e2e.py makes them)."""
    from authn.scenario import Broadcast, simulate_flight
    from signatures.profiles import shipped_profiles
    from signatures.radar import get_preset
    from signatures.recording import write_recording
    from signatures.sim.scene import Scene

    sc = Scene(kind="uav", profile=shipped_profiles().get(flies), snr_db=20.0, range_m=400.0,
               radial_speed_mps=3.0, elevation_deg=10.0)
    bc = Broadcast(serial=serial, offset_along_los_m=offset) if serial else None
    rec, _ = simulate_flight(sc, get_preset("paper"), seed, bc, azimuth_deg=60.0,
                             start_time=datetime.now(timezone.utc))
    return write_recording(rec, out / f"{name}.h5")
