"""Witnesses: the audit log's heads kept where the log's own machine cannot rewrite them.

Why: every other copy of a head (the database, the latest-head file, the STH log) sits
on or beside the machine that holds the database and the log key. Someone who controls
that machine can rewrite the log and re-sign it with the readable key. A witness holds
every head it was given in an append-only store on another host and accepts a new head
only with an RFC 9162 consistency proof from the newest one it holds (as a C2SP
tlog-witness does), so a rewrite, even re-signed with the real key, either is refused
by the witness or leaves the witness holding a head the log no longer extends, which
`authn audit verify` and the next append report.

Two kinds, one store:
- `DIR`: a folder (a mount of another host, ideally append-only): `WitnessStore` runs
  in the writer's process. A head published there is checked the same way.
- `http(s)://HOST:PORT`: `authn audit witness serve --dir DIR --public-key LOG.pub`
  on the other host, the same store behind two routes (authn.audit.witness_http, on uvicorn):
  `POST /add-checkpoint` (body: "old <size>\\n", one base64 proof hash per line, a blank
  line, then the signed note; 200, or 409 with the witness's newest head when the proof
  fails) and `GET /checkpoints?origin=O` (every held head, JSON lines).

A store file is `<sha256(origin)[:16]>.jsonl`: one authn-checkpoint/1 object per line,
oldest first, appended under an exclusive lock with one write(2).
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import authn.audit.merkle as merkle
from core.errors import AuthnError, SystemFault, one_line
from core.settings import current
from authn.audit.head_files import lines_from_end
from authn.audit.tree_head import SignedTreeHead, parse_note

if TYPE_CHECKING:
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey

TIMEOUT_S = 5.0


class Conflict(AuthnError):
    """The witness holds a head the offered one does not extend."""


class WitnessStore:
    """Append-only heads per origin in one folder, each new one proven to extend the last."""

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root).expanduser()
        self.name = str(self.root)

    def _file(self, origin: str) -> Path:
        return self.root / f"{hashlib.sha256(origin.encode()).hexdigest()[:16]}.jsonl"

    def heads(self, origin: str) -> list[SignedTreeHead]:
        """Every head held for `origin`, oldest first (lines that do not parse: a fault)."""
        path = self._file(origin)
        try:
            return _held(path.read_bytes(), origin, f"witness {path}")
        except FileNotFoundError:
            return []
        except OSError as exc:
            raise SystemFault(f"witness {path}: cannot read ({exc.strerror})") from None

    def newest(self, origin: str) -> SignedTreeHead | None:
        """The last head held for `origin` (its file's last line, read from the end: each head
        appended extends the one before, so the last is the newest)."""
        path = self._file(origin)
        for line in lines_from_end(path, "witness file"):
            if line.strip():
                held = _held(line, origin, f"witness {path} (last line)")
                return held[0] if held else None
        return None

    def add(self, head: SignedTreeHead, old_size: int, proof: Sequence[bytes],
            public_keys: Sequence[Ed25519PublicKey]) -> None:
        """Keep `head` if a key in `public_keys` signed it and `proof` proves it extends the
        newest head held for its origin (of size `old_size`); else Conflict / AuthnError."""
        import fcntl

        if head.origin is None:
            raise AuthnError("a witness keeps C2SP checkpoints only (this head names no log)")
        if not any(head.verify_signature(k) for k in public_keys):
            raise AuthnError("witness: the head is not signed by the log's key")
        path = self._file(head.origin)
        try:
            self.root.mkdir(parents=True, exist_ok=True)
            lock = os.open(str(path) + ".lock", os.O_CREAT | os.O_RDWR, 0o644)
        except OSError as exc:
            raise SystemFault(f"witness {self.root}: cannot write ({exc.strerror})") from None
        try:
            fcntl.flock(lock, fcntl.LOCK_EX)
            last = self.newest(head.origin)
            if last is not None:
                if last.tree_size != old_size:
                    raise Conflict(f"witness holds size {last.tree_size}, the proof starts at {old_size}")
                if not merkle.verify_consistency(last.tree_size, head.tree_size, last.root, head.root, proof):
                    raise Conflict(f"the head of size {head.tree_size} does not extend the witnessed head of "
                                   f"size {last.tree_size} (rewritten history)")
                if head.tree_size == last.tree_size and head.signature == last.signature:
                    return  # already held
            line = (head.to_json() + "\n").encode()
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
            try:
                os.write(fd, line)
                os.fsync(fd)
            finally:
                os.close(fd)
        except OSError as exc:
            raise SystemFault(f"witness {path}: cannot append ({exc.strerror})") from None
        finally:
            os.close(lock)


class HttpWitness:
    """A witness endpoint (`authn audit witness serve`) seen from the log's side."""

    def __init__(self, url: str) -> None:
        self.url = url.rstrip("/")
        self.name = self.url

    def heads(self, origin: str) -> list[SignedTreeHead]:
        import urllib.parse

        body = self._request("GET", "/checkpoints?origin=" + urllib.parse.quote(origin, safe=""), None)
        return _held(body, origin, f"witness {self.url}")

    def newest(self, origin: str) -> SignedTreeHead | None:
        held = self.heads(origin)
        return held[-1] if held else None

    def add(self, head: SignedTreeHead, old_size: int, proof: Sequence[bytes],
            public_keys: Sequence[Ed25519PublicKey]) -> None:
        self._request("POST", "/add-checkpoint", add_request(head, old_size, proof))

    def _request(self, method: str, path: str, data: bytes | None) -> bytes:
        import urllib.error
        import urllib.request

        req = urllib.request.Request(self.url + path, data=data, method=method,
                                     headers={"Content-Type": "text/plain; charset=utf-8"})
        try:
            with urllib.request.urlopen(req, timeout=TIMEOUT_S) as resp:  # the operator's URL
                return resp.read(1 << 24)
        except urllib.error.HTTPError as exc:
            text = exc.read(2000).decode("utf-8", "replace").strip().splitlines()
            if exc.code == 409:
                raise Conflict(f"witness {self.url}: {text[0] if text else 'conflict'}") from None
            raise SystemFault(f"witness {self.url}: HTTP {exc.code}") from None
        except (urllib.error.URLError, OSError) as exc:
            raise SystemFault(f"witness {self.url}: not reached ({getattr(exc, 'reason', exc)})") from None


def _held(text: bytes, origin: str, where: str) -> list[SignedTreeHead]:
    """The heads of `origin` in a witness's JSON lines (a line that does not parse: a fault)."""
    out = []
    for i, line in enumerate(text.splitlines(), 1):
        if line.strip():
            try:
                out.append(SignedTreeHead.from_json(line, f"{where} line {i}"))
            except AuthnError as exc:
                raise SystemFault(str(exc)) from None
    return [h for h in out if h.origin == origin]


def add_request(head: SignedTreeHead, old_size: int, proof: Sequence[bytes]) -> bytes:
    lines = [f"old {old_size}"] + [base64.b64encode(p).decode() for p in proof]
    return ("\n".join(lines) + "\n\n" + head.note()).encode()


def parse_add_request(body: bytes) -> tuple[SignedTreeHead, int, list[bytes]]:
    """The inverse of add_request (AuthnError on anything malformed)."""
    try:
        text = body.decode("utf-8")
        head_part, sep, note = text.partition("\n\n")
        lines = head_part.split("\n")
        if not sep or not lines[0].startswith("old ") or not lines[0][4:].isdigit() or len(lines) > 65:
            raise ValueError
        proof = [base64.b64decode(p, validate=True) for p in lines[1:]]
        if any(len(p) != 32 for p in proof):
            raise ValueError
    except (UnicodeDecodeError, ValueError, binascii.Error):
        raise AuthnError("not an add-checkpoint request") from None
    return parse_note(note, "add-checkpoint")[0], int(lines[0][4:]), proof


def open_witness(spec: str | None) -> WitnessStore | HttpWitness | None:
    """--witness, else $AUTHN_AUDIT_WITNESS: a folder or an http(s) URL (None: no witness)."""
    spec = spec or current().audit_witness
    if spec is None:
        return None
    if spec.startswith(("http://", "https://")):
        return HttpWitness(spec)
    return WitnessStore(spec)


class Endpoint:
    """The witness's two operations as HTTP answers (status, text); authn.audit.witness_http
    carries them. `public_keys` is read on every add."""

    def __init__(self, store: WitnessStore, public_keys: Sequence[Ed25519PublicKey]) -> None:
        self.store = store
        self.public_keys = public_keys

    def checkpoints(self, origin: str) -> tuple[int, str]:
        """200 and every head held for `origin` as JSON lines; 500 when the store cannot be read."""
        try:
            return 200, "".join(h.to_json() + "\n" for h in self.store.heads(origin))
        except SystemFault as exc:
            return 500, one_line(exc) + "\n"

    def add(self, body: bytes) -> tuple[int, str]:
        """200 when the head in an add-checkpoint `body` is kept; 409 when it does not extend the
        newest held, 400 when malformed or not the log's, 500 when the store cannot be written."""
        try:
            head, old, proof = parse_add_request(body)
            self.store.add(head, old, proof, self.public_keys)
        except Conflict as exc:
            return 409, f"{exc}\n"
        except AuthnError as exc:
            return 400, f"{exc}\n"
        except SystemFault as exc:
            return 500, one_line(exc) + "\n"
        return 200, "ok\n"


def serve(store: WitnessStore, public_keys: Sequence[Ed25519PublicKey], host: str, port: int) -> None:
    """Run the witness endpoint until interrupted (authn.audit.witness_http: uvicorn, as `authn serve`)."""
    from authn.audit.witness_http import run

    run(Endpoint(store, public_keys), host, port)
