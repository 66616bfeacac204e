"""The audit log's Ed25519 signing key and its signed tree heads (C2SP checkpoints).

Why a key outside the database: the hash chain and the Merkle tree use no secret, so
anyone who can write the database can rewrite history and recompute every hash. A
signature by a key the database never holds cannot be recomputed; a head kept outside
the database (a file, a witness) fixes the log's contents up to its size.

Key file: PKCS#8 PEM, mode 0600, written atomically (a temporary file hard-linked into
place, so concurrent first uses agree on one key). Path: `--log-key`, else
$AUTHN_LOG_KEY, else `audit-log-key.pem` in the user data directory. Loading never
creates it: the audit writer creates it only for a log that has no signed head yet
(authn.audit), and `authn audit rotate-key` replaces it deliberately, keeping the
retired public keys in `<key>.retired.pub.pem`. Its id is SHA-256 of the raw public key.

Heads are C2SP checkpoints (https://c2sp.org/tlog-checkpoint) whose origin line names the
log, so a head of one log never verifies for another signed with the same key; heads
written before origins existed (authn-sth/1 JSON, no origin) still verify.
`cryptography` is imported only when a key is loaded or a signature checked.
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import json
import os
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from core.errors import AuthnError, SystemFault
from core.parsing import loads_json
from core.pem import PemError, private_key, public_key, raw_public
from core.settings import current

STH_FORMAT = "authn-sth/1"  # legacy heads: JSON, no origin
CHECKPOINT_FORMAT = "authn-checkpoint/1"  # JSON carrying a C2SP checkpoint and its fields
TIMESTAMP_EXTENSION = "authn-timestamp-ms"

if TYPE_CHECKING:
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey, Ed25519PublicKey


def canonical_json(obj: object) -> str:
    """One byte-exact encoding: sorted keys, no spaces, UTF-8, finite numbers only."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)


def default_key_path() -> Path:
    from platformdirs import user_data_dir

    return Path(user_data_dir("authn")) / "audit-log-key.pem"


def key_path(explicit: str | Path | None = None) -> Path:
    """--log-key, else $AUTHN_LOG_KEY, else the user data directory."""
    return Path(explicit or current().log_key or default_key_path()).expanduser()


def sth_log_path(explicit: str | Path | None = None, key: str | Path | None = None) -> Path:
    """Where automatic STHs are appended (JSON lines): $AUTHN_AUDIT_STH_LOG, else beside the key."""
    explicit = explicit or current().audit_sth_log
    if explicit:
        return Path(explicit).expanduser()
    return key_path(key).parent / "audit-sth.jsonl"


def key_id(public_raw: bytes) -> str:
    return hashlib.sha256(public_raw).hexdigest()


class LogKey:
    """A loaded Ed25519 private key (signs STHs) with its public half."""

    def __init__(self, private: Ed25519PrivateKey, path: Path) -> None:
        self._private = private
        self.path = path
        self.public_key = private.public_key()
        self.public_raw = raw_public(self.public_key)
        self.key_id = key_id(self.public_raw)
        self._vouched: set[tuple[bytes, str]] = set()  # (signed bytes, signature) made or checked here

    def vouches_for(self, sth: "SignedTreeHead") -> bool:
        """Whether `sth` carries this key's signature; each signature is checked once per
        process (an append reads back the heads it signed itself, often the same one twice)."""
        seen = (sth.signed_bytes(), sth.signature)  # the fields too: a signature moved onto other fields fails
        if seen in self._vouched:
            return True
        if not sth.verify_signature(self.public_key):
            return False
        self._vouched.add(seen)
        return True

    @classmethod
    def load(cls, path: str | Path | None = None, *, create: bool = False) -> "LogKey":
        """The key at `path` (see key_path); generated there when absent only with `create`
        (the audit writer's decision: never for a log that already has signed heads)."""
        p = key_path(path)
        if not p.exists():
            if not create:
                raise SystemFault(f"audit log key {p} does not exist (it is created by the first audit write)")
            create_key_file(p)
        try:
            data = p.read_bytes()
        except OSError as exc:
            raise SystemFault(f"audit log key {p}: cannot read ({exc.strerror})") from None
        try:
            return cls(private_key(data), p)
        except PemError as exc:
            what = "not an unencrypted PEM private key" if exc.kind == "pem" else "not an Ed25519 key"
            raise SystemFault(f"audit log key {p}: {what}") from None

    def public_pem(self) -> str:
        from cryptography.hazmat.primitives import serialization

        return self._private.public_key().public_bytes(
            serialization.Encoding.PEM, serialization.PublicFormat.SubjectPublicKeyInfo).decode()

    def sign_tree_head(self, tree_size: int, root_hash: bytes, timestamp_ms: int, origin: str) -> "SignedTreeHead":
        """A C2SP checkpoint of the log named `origin`, signed by this key."""
        check_origin(origin)
        unsigned = SignedTreeHead(tree_size, timestamp_ms, root_hash.hex(), self.key_id, "", origin)
        raw = self._private.sign(unsigned.signed_bytes())
        sig = base64.b64encode(note_key_hash(origin, self.public_raw) + raw).decode()
        self._vouched.add((unsigned.signed_bytes(), sig))
        return SignedTreeHead(tree_size, timestamp_ms, root_hash.hex(), self.key_id, sig, origin)

    def sign(self, data: bytes) -> bytes:
        """A bare Ed25519 signature of `data` (authn.audit.edge signs the right edge with it)."""
        return bytes(self._private.sign(data))


def retired_keys_path(key: Path) -> Path:
    """Public keys this log signed with before `authn audit rotate-key` (PEM blocks, oldest first)."""
    return key.with_name(key.name + ".retired.pub.pem")


def load_retired_keys(key: Path) -> list[Ed25519PublicKey]:
    """The retired public keys beside the key file (none: an empty list)."""
    path = retired_keys_path(key)
    try:
        text = path.read_bytes()
    except FileNotFoundError:
        return []
    except OSError as exc:
        raise SystemFault(f"{path}: cannot read the retired log keys ({exc.strerror})") from None
    out = []
    for block in text.split(b"-----END PUBLIC KEY-----")[:-1]:
        try:
            out.append(public_key(block + b"-----END PUBLIC KEY-----\n"))
        except PemError:
            raise SystemFault(f"{path}: not a list of PEM public keys") from None
    return out


def create_key_file(p: Path) -> None:
    """A new Ed25519 key at `p` (0600, atomic; another process's key wins a race)."""
    from cryptography.hazmat.primitives import serialization
    from cryptography.hazmat.primitives.asymmetric import ed25519

    pem = ed25519.Ed25519PrivateKey.generate().private_bytes(
        serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption())
    tmp = p.with_name(f".{p.name}.{os.getpid()}.tmp")
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(fd, "wb") as fh:
            fh.write(pem)
            fh.flush()
            os.fsync(fh.fileno())
        try:
            os.link(tmp, p)  # atomic, and fails if another process won the race
        except FileExistsError:
            pass
    except OSError as exc:
        raise SystemFault(f"audit log key {p}: cannot create ({exc.strerror})") from None
    finally:
        try:
            tmp.unlink()
        except OSError:
            pass


def load_public_key(path: str | Path) -> Ed25519PublicKey:
    """An Ed25519 public key from a PEM file (public key, or the private key itself)."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise AuthnError(f"{p}: cannot read public key ({exc.strerror})") from None
    try:
        return public_key(data, private_ok=True)
    except PemError as exc:
        raise AuthnError(f"{p}: not a PEM Ed25519 public key" if exc.kind == "pem" else
                         f"{p}: not an Ed25519 key") from None


@dataclass(frozen=True)
class SignedTreeHead:
    """A signed tree head: a C2SP checkpoint (`origin` set) or a legacy authn-sth/1 head.

    Checkpoint: the signed note text is "<origin>\\n<tree_size>\\n<base64 root>\\n" plus one
    extension line "authn-timestamp-ms <ms>\\n"; `signature` is the note's signature field,
    base64(4-byte key hash || 64-byte Ed25519 signature), the key hash being
    SHA-256(origin || 0x0A || 0x01 || public key)[:4] (C2SP signed-note). `log_key_id` is
    SHA-256 of the raw public key (hex), or the 8-hex key hash when parsed from a bare note.
    Legacy heads (no origin) sign the canonical JSON of the other fields and name no log."""

    tree_size: int
    timestamp: int  # ms since the epoch, UTC
    root_hash: str  # hex
    log_key_id: str
    signature: str  # base64
    origin: str | None = None

    @property
    def root(self) -> bytes:
        return bytes.fromhex(self.root_hash)

    def note_body(self) -> str:
        root = base64.b64encode(self.root).decode()
        return f"{self.origin}\n{self.tree_size}\n{root}\n{TIMESTAMP_EXTENSION} {self.timestamp}\n"

    def signed_bytes(self) -> bytes:
        if self.origin is None:
            return canonical_json({"format": STH_FORMAT, "tree_size": self.tree_size, "timestamp": self.timestamp,
                                   "root_hash": self.root_hash, "log_key_id": self.log_key_id}).encode()
        return self.note_body().encode()

    def note(self, *cosigned: "SignedTreeHead") -> str:
        """The C2SP signed note: body, blank line, one signature line per head of this body."""
        if self.origin is None:
            raise AuthnError("a legacy authn-sth/1 head has no checkpoint form")
        sigs = "".join(f"\u2014 {self.origin} {h.signature}\n" for h in (self, *cosigned))
        return self.note_body() + "\n" + sigs

    def to_dict(self) -> dict[str, Any]:
        if self.origin is None:
            return {"format": STH_FORMAT, "tree_size": self.tree_size, "timestamp": self.timestamp,
                    "root_hash": self.root_hash, "log_key_id": self.log_key_id, "signature": self.signature}
        return {"format": CHECKPOINT_FORMAT, "origin": self.origin, "tree_size": self.tree_size,
                "timestamp": self.timestamp, "root_hash": self.root_hash, "log_key_id": self.log_key_id,
                "signature": self.signature, "checkpoint": self.note()}

    def to_json(self) -> str:
        return canonical_json(self.to_dict())

    @classmethod
    def from_dict(cls, doc: object, what: str = "signed tree head") -> "SignedTreeHead":
        try:
            if not isinstance(doc, dict) or doc.get("format") not in (STH_FORMAT, CHECKPOINT_FORMAT):
                raise ValueError
            size, ts = doc["tree_size"], doc["timestamp"]
            root, kid, sig = doc["root_hash"], doc["log_key_id"], doc["signature"]
            origin = doc["origin"] if doc["format"] == CHECKPOINT_FORMAT else None
            if not (type(size) is int and type(ts) is int and size >= 0 and ts >= 0):
                raise ValueError
            if not all(isinstance(x, str) for x in (root, kid, sig)):
                raise ValueError
            if len(bytes.fromhex(root)) != 32 or root != root.lower() or kid != kid.lower() \
                    or len(bytes.fromhex(kid)) not in ((32,) if origin is None else (4, 32)):
                raise ValueError
            if len(base64.b64decode(sig, validate=True)) != (64 if origin is None else 68):
                raise ValueError
            if origin is not None:
                check_origin(origin)
        except (ValueError, KeyError, TypeError, binascii.Error):
            raise AuthnError(f"{what}: not an {CHECKPOINT_FORMAT} or {STH_FORMAT} document") from None
        return cls(size, ts, root, kid, sig, origin)

    @classmethod
    def from_json(cls, text: str | bytes, what: str = "signed tree head") -> "SignedTreeHead":
        """A head from JSON (either format), or the first signature of a bare C2SP note."""
        try:
            if isinstance(text, bytes):
                text = text.decode("utf-8")
            if not text.lstrip().startswith("{"):
                return parse_note(text, what)[0]
            doc = loads_json(text)
        except (UnicodeDecodeError, ValueError):
            raise AuthnError(f"{what}: not an {CHECKPOINT_FORMAT} document or C2SP checkpoint") from None
        return cls.from_dict(doc, what)

    @classmethod
    def read(cls, path: str | Path) -> "SignedTreeHead":
        p = Path(path)
        try:
            data = p.read_bytes()
        except OSError as exc:
            raise AuthnError(f"{p}: cannot read signed tree head ({exc.strerror})") from None
        return cls.from_json(data, str(p))

    def verify_signature(self, public_key: Ed25519PublicKey) -> bool:
        """Whether the signature is this key's over these fields (key id and key hash match)."""
        from cryptography.exceptions import InvalidSignature

        raw = raw_public(public_key)
        sig = base64.b64decode(self.signature)
        if self.origin is None:
            if key_id(raw) != self.log_key_id:
                return False
        else:
            hint = note_key_hash(self.origin, raw)
            if sig[:4] != hint or self.log_key_id not in (key_id(raw), hint.hex()):
                return False
            sig = sig[4:]
        try:
            public_key.verify(sig, self.signed_bytes())
        except InvalidSignature:
            return False
        return True


def note_key_hash(name: str, public_raw_key: bytes) -> bytes:
    """C2SP signed-note key hash of an Ed25519 key: SHA-256(name || 0x0A || 0x01 || key)[:4]."""
    return hashlib.sha256(name.encode() + b"\n\x01" + public_raw_key).digest()[:4]


_ORIGIN = re.compile(r"[^\s+\x00-\x1f\x7f]{1,256}")


def check_origin(origin: object) -> None:
    """A note key name: non-empty UTF-8 without whitespace, '+' or control characters."""
    if not isinstance(origin, str) or not _ORIGIN.fullmatch(origin):
        raise ValueError(f"not a checkpoint origin: {origin!r}")


def parse_note(text: str, what: str = "checkpoint") -> list[SignedTreeHead]:
    """Every signature of a C2SP checkpoint note, as heads (unverified; key id = the key hash)."""
    try:
        body, sep, sigs = text.rpartition("\n\n")
        if not sep or len(text) > 1 << 16 or any(ord(c) < 0x20 and c != "\n" for c in text):
            raise ValueError
        lines = body.split("\n")
        origin, size_text, root_b64, *ext = lines
        check_origin(origin)
        if not size_text.isdigit() or (size_text != "0" and size_text.startswith("0")):
            raise ValueError
        root = base64.b64decode(root_b64, validate=True)
        if len(root) != 32:
            raise ValueError
        timestamp = 0
        for line in ext:
            if not line:
                raise ValueError
            name, _, value = line.partition(" ")
            if name == TIMESTAMP_EXTENSION and value.isdigit():
                timestamp = int(value)
        heads = []
        for line in sigs.split("\n"):
            if not line:
                continue
            dash, name, sig = line.split(" ")
            if dash != "\u2014":
                raise ValueError
            raw = base64.b64decode(sig, validate=True)
            if name != origin or len(raw) != 68:
                continue  # another signer (a witness's cosignature): not a log head
            heads.append(SignedTreeHead(int(size_text), timestamp, root.hex(), raw[:4].hex(), sig, origin))
        if not heads:
            raise ValueError
    except (ValueError, binascii.Error):
        raise AuthnError(f"{what}: not a C2SP checkpoint signed by its origin") from None
    return heads


def read_sth_log(path: Path) -> list[tuple[str | None, SignedTreeHead]]:
    """Every well-formed STH line of an external STH file (a missing file is an empty list)."""
    return scan_sth_log(path)[0]


def scan_sth_log(path: Path) -> tuple[list[tuple[str | None, SignedTreeHead]], list[int]]:
    """The well-formed STH lines of an STH file, and the numbers of the non-blank lines that
    are not one (damage `verify` reports). Lines carry the STH fields plus "db" (which
    database they vouch for). A missing file has neither."""
    try:
        lines = path.read_bytes().splitlines()
    except FileNotFoundError:
        return [], []
    except OSError as exc:
        raise SystemFault(f"{path}: cannot read the STH log ({exc.strerror})") from None
    out: list[tuple[str | None, SignedTreeHead]] = []
    bad: list[int] = []
    for number, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        try:
            doc = loads_json(line.decode("utf-8"))
            out.append((doc.get("db"), SignedTreeHead.from_dict({k: v for k, v in doc.items() if k != "db"})))
        except (UnicodeDecodeError, ValueError, AuthnError, AttributeError):
            bad.append(number)
    return out, bad


def lines_from_end(path: Path, what: str) -> Iterator[bytes]:
    """The lines of a file, last first, read backwards a block at a time: the newest head of
    an append-only file that grows with the log, without reading all of it (none: no file)."""
    try:
        fh = open(path, "rb")
    except FileNotFoundError:
        return
    except OSError as exc:
        raise SystemFault(f"{path}: cannot read the {what} ({exc.strerror})") from None
    with fh:
        end = fh.seek(0, os.SEEK_END)
        tail = b""
        while end > 0:
            start = max(0, end - (1 << 16))
            fh.seek(start)
            block = fh.read(end - start) + tail
            lines = block.split(b"\n")
            tail = lines.pop(0) if start > 0 else b""  # maybe cut: joined with the next block
            yield from reversed(lines)
            end = start


def newest_in_sth_log(path: Path, db_label: str) -> SignedTreeHead | None:
    """The last well-formed line for `db_label` (the writer asks on every append)."""
    for line in lines_from_end(path, "STH log"):
        if db_label.encode() not in line:
            continue
        try:
            doc = loads_json(line.decode("utf-8"))
            if doc.get("db") == db_label:
                return SignedTreeHead.from_dict({k: v for k, v in doc.items() if k != "db"})
        except (UnicodeDecodeError, ValueError, AuthnError, AttributeError):
            continue
    return None


def append_sth_log(path: Path, sth: SignedTreeHead, db_label: str) -> None:
    """One JSON line, one write(2) on an O_APPEND descriptor (concurrent writers do not interleave)."""
    line = (canonical_json({**sth.to_dict(), "db": db_label}) + "\n").encode()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
        try:
            os.write(fd, line)
        finally:
            os.close(fd)
    except OSError as exc:
        raise SystemFault(f"{path}: cannot append to the STH log ({exc.strerror})") from None


def latest_head_path(sth_log: Path, db_label: str) -> Path:
    """The newest signed head of one database: a small file beside the STH log (one per
    database, named by a digest of its label, so several databases can share the folder)."""
    return sth_log.with_name(f"{sth_log.stem}-latest-{hashlib.sha256(db_label.encode()).hexdigest()[:16]}.json")


def read_latest_head(path: Path) -> SignedTreeHead | None:
    """The head in a latest-head file (None when there is none yet); a file that does not
    parse is a system fault: someone damaged the log's external state."""
    try:
        text = path.read_bytes()
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise SystemFault(f"{path}: cannot read the latest signed head ({exc.strerror})") from None
    try:
        doc = loads_json(text.decode("utf-8"))
        return SignedTreeHead.from_dict({k: v for k, v in doc.items() if k != "db"})
    except (UnicodeDecodeError, ValueError, AuthnError, AttributeError):
        raise SystemFault(f"{path}: the latest signed head is not an authn-sth/1 document") from None


def write_latest_head(path: Path, sth: SignedTreeHead, db_label: str) -> None:
    """Replace the latest-head file with `sth` unless it already holds a larger tree: an
    exclusive flock orders concurrent writers, and write-then-rename keeps the file whole."""
    import fcntl

    data = (canonical_json({**sth.to_dict(), "db": db_label}) + "\n").encode()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        lock = os.open(str(path) + ".lock", os.O_CREAT | os.O_RDWR, 0o644)
        try:
            fcntl.flock(lock, fcntl.LOCK_EX)
            current = read_latest_head(path)
            if current is not None and current.tree_size > sth.tree_size:
                return
            tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
            tmp.write_bytes(data)
            os.replace(tmp, path)
        finally:
            os.close(lock)
    except OSError as exc:
        raise SystemFault(f"{path}: cannot write the latest signed head ({exc.strerror})") from None
