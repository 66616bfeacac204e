"""`authn audit witness serve`: the witness endpoint on the product's one HTTP stack (uvicorn),
with its routes, status codes and body limit, tried against a real server."""

from __future__ import annotations

import ast
import os
import socket
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest

from authn.audit.logkey import LogKey
from authn.audit.tree_head import SignedTreeHead
from authn.audit.witness import Endpoint, WitnessStore, add_request
from tests.service.server import free_port

ROOT = Path(__file__).resolve().parents[2]
PRODUCT = ("core", "remoteid", "signatures", "registry", "authn")
ORIGIN = "witness.test/log"


def _imported(path: Path) -> set[str]:
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            names.add(node.module)
    return names


def test_the_product_has_one_http_server_stack() -> None:
    """No module of the product runs a server of the standard library: HTTP is served by
    uvicorn (the service and the witness alike)."""
    other = ("http.server", "socketserver", "wsgiref", "wsgiref.simple_server")
    found = sorted(f"{p.relative_to(ROOT)}: {name}" for package in PRODUCT for p in (ROOT / package).rglob("*.py")
                   for name in _imported(p) if name in other)
    assert not found, found


def _call(url: str, method: str = "GET", body: bytes | None = None,
          headers: dict[str, str] | None = None) -> tuple[int, str, dict[str, str]]:
    req = urllib.request.Request(url, data=body, method=method, headers=headers or {})
    try:
        with urllib.request.urlopen(req, timeout=10) as resp:
            return resp.status, resp.read().decode(), dict(resp.headers)
    except urllib.error.HTTPError as exc:
        return exc.code, exc.read().decode(), dict(exc.headers)


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, LogKey, Path]]:
    """`authn audit witness serve` in a subprocess, as an operator starts it."""
    tmp = tmp_path_factory.mktemp("witness")
    key = LogKey.load(tmp / "log.pem", create=True)
    (tmp / "log.pub").write_text(key.public_pem())
    port = free_port()
    proc = subprocess.Popen([sys.executable, "-m", "authn", "audit", "witness", "serve", "--dir", str(tmp / "held"),
                             "--public-key", str(tmp / "log.pub"), "--port", str(port)],
                            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    url = f"http://127.0.0.1:{port}"
    try:
        for _ in range(300):
            try:
                _call(url + "/checkpoints?origin=x")
                break
            except OSError:
                assert proc.poll() is None, proc.stderr.read().decode() if proc.stderr else ""
                time.sleep(0.1)
        yield url, key, tmp / "held"
    finally:
        proc.terminate()
        proc.wait(timeout=30)


def test_the_witness_is_served_by_uvicorn(served: tuple[str, LogKey, Path]) -> None:
    status, body, headers = _call(served[0] + "/checkpoints?origin=nobody")
    assert (status, body) == (200, "")
    assert headers.get("server") == "uvicorn" and headers["content-type"] == "text/plain; charset=utf-8"


@pytest.mark.parametrize(("method", "path", "body", "status", "text"), [
    ("GET", "/checkpoints", None, 404, "GET /checkpoints?origin=ORIGIN\n"),
    ("GET", "/checkpoints?origin=", None, 404, "GET /checkpoints?origin=ORIGIN\n"),
    ("GET", "/elsewhere?origin=o", None, 404, "GET /checkpoints?origin=ORIGIN\n"),
    ("POST", "/elsewhere", b"old 0\n\nx", 400, "POST /add-checkpoint with a body under 64 KiB\n"),
    ("POST", "/add-checkpoint", b"x" * ((1 << 16) + 1), 400, "POST /add-checkpoint with a body under 64 KiB\n"),
    ("POST", "/add-checkpoint", b"hello", 400, "not an add-checkpoint request\n"),
    ("PUT", "/add-checkpoint", b"", 501, None),
])
def test_routes_status_codes_and_body_limit(served: tuple[str, LogKey, Path], method: str, path: str,
                                            body: bytes | None, status: int, text: str | None) -> None:
    got, answer, _ = _call(served[0] + path, method, body)
    assert got == status
    if text is not None:
        assert answer == text


def test_a_head_is_kept_and_a_rewrite_is_refused_409(served: tuple[str, LogKey, Path]) -> None:
    url, key, _ = served
    origin = ORIGIN + "/kept"
    head = key.sign_tree_head(1, b"\x01" * 32, 1000, origin)
    assert _call(url + "/add-checkpoint", "POST", add_request(head, 0, []))[:2] == (200, "ok\n")
    status, body, _ = _call(url + "/checkpoints?origin=" + urllib.request.quote(origin, safe=""))
    held = [SignedTreeHead.from_json(line) for line in body.splitlines()]
    assert status == 200 and [(h.tree_size, h.root_hash, h.signature) for h in held] == \
        [(1, head.root_hash, head.signature)]
    other = key.sign_tree_head(1, b"\x02" * 32, 2000, origin)
    status, body, _ = _call(url + "/add-checkpoint", "POST", add_request(other, 1, []))
    assert status == 409 and "rewritten history" in body


def test_a_damaged_store_answers_500_in_one_line(served: tuple[str, LogKey, Path]) -> None:
    """A store file that does not parse is the witness's fault: a 500 naming it, not a dropped connection."""
    url, _, held = served
    origin = ORIGIN + "/damaged"
    held.mkdir(exist_ok=True)
    (WitnessStore(held)._file(origin)).write_text("not a head\n")
    status, body, _ = _call(url + "/checkpoints?origin=" + urllib.request.quote(origin, safe=""))
    assert status == 500 and body.count("\n") == 1 and "witness" in body


def test_a_taken_port_is_a_system_fault(served: tuple[str, LogKey, Path], tmp_path: Path) -> None:
    port = served[0].rsplit(":", 1)[1]
    (tmp_path / "log.pub").write_text(served[1].public_pem())
    done = subprocess.run([sys.executable, "-m", "authn", "audit", "witness", "serve", "--dir", str(tmp_path),
                           "--public-key", str(tmp_path / "log.pub"), "--port", port],
                          cwd=ROOT, capture_output=True, text=True, timeout=60)
    errors = [line for line in done.stderr.splitlines() if line.startswith("error:")]
    assert done.returncode == 3 and "Traceback" not in done.stderr, done.stderr
    assert errors == [f"error: witness: cannot listen on 127.0.0.1:{port} (Address already in use)"]


@pytest.fixture
def quick(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> str:
    """The witness in a thread of this process, a client given 0.5 s for its head and body."""
    import authn.audit.witness_http as wh

    monkeypatch.setattr(wh, "REQUEST_TIMEOUT_S", 0.5)
    port = free_port()
    threading.Thread(target=wh.run, args=(Endpoint(WitnessStore(tmp_path), []), "127.0.0.1", port),
                     daemon=True).start()
    for _ in range(100):
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1).close()
            break
        except OSError:
            time.sleep(0.05)
    return f"127.0.0.1:{port}"


def _closed_after(conn: socket.socket, send: bytes) -> tuple[bytes, float]:
    conn.settimeout(10)
    conn.sendall(send)
    start, got = time.monotonic(), b""
    while chunk := conn.recv(4096):
        got += chunk
    return got, time.monotonic() - start


@pytest.mark.parametrize("send", [b"", b"GET /checkpoints?ori"])
def test_a_client_that_never_finishes_its_request_head_is_closed(quick: str, send: bytes) -> None:
    host, port = quick.split(":")
    with socket.create_connection((host, int(port))) as conn:
        got, waited = _closed_after(conn, send)
    assert got == b"" and waited < 9  # closed by the witness (0.5 s), not by this client's 10 s timeout


def test_a_body_that_never_arrives_is_answered_408(quick: str) -> None:
    host, port = quick.split(":")
    with socket.create_connection((host, int(port))) as conn:
        got, waited = _closed_after(conn, b"POST /add-checkpoint HTTP/1.1\r\nHost: w\r\nContent-Length: 100\r\n\r\nold")
    assert got.startswith(b"HTTP/1.1 408 ") and waited < 9


def test_the_witness_does_not_load_at_check_time() -> None:
    """The server's modules stay out of everything but `authn audit witness serve`."""
    code = ("import sys, authn.audit.witness, authn.audit.writer; "
            "print(sorted(m for m in ('uvicorn', 'starlette', 'authn.audit.witness_http') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=60,
                         env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert out.returncode == 0 and out.stdout.strip() == "[]", out.stderr
