"""The audit log's Ed25519 signing key and its signed tree heads (STHs).

Why a key outside the database: the hash chain and the Merkle tree use no secret, so
anyone who can write the database can rewrite history and recompute every hash. A
signature by a key the database never holds cannot be recomputed; an STH kept outside
the database (a file, a witness) fixes the log's contents up to its size.

Key file: PKCS#8 PEM, created on first use with mode 0600 (atomically: written to a
temporary file and hard-linked into place, so concurrent first uses agree on one key).
Path: `--log-key`, else $AUTHN_LOG_KEY, else `audit-log-key.pem` in the user data
directory (next to the default SQLite database). The public key is exported as
SubjectPublicKeyInfo PEM; its id is SHA-256 of the raw 32-byte key, hex.

STH (JSON): {"format": "authn-sth/1", "tree_size", "timestamp" (ms since the epoch, UTC),
"root_hash" (hex), "log_key_id" (hex), "signature" (base64)}. The signature is Ed25519
over the UTF-8 canonical JSON (sorted keys, no spaces) of every other field.
`cryptography` is imported only when a key is loaded or a signature checked.
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from authn.errors import AuthnError, SystemFault

ENV_KEY = "AUTHN_LOG_KEY"
ENV_STH_LOG = "AUTHN_AUDIT_STH_LOG"
STH_FORMAT = "authn-sth/1"


def canonical_json(obj: Any) -> str:
    """One byte-exact encoding: sorted keys, no spaces, UTF-8, finite numbers only."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)


def default_key_path() -> Path:
    from platformdirs import user_data_dir

    return Path(user_data_dir("authn")) / "audit-log-key.pem"


def key_path(explicit: str | Path | None = None) -> Path:
    """--log-key, else $AUTHN_LOG_KEY, else the user data directory."""
    return Path(explicit or os.environ.get(ENV_KEY) or default_key_path()).expanduser()


def sth_log_path(explicit: str | Path | None = None, key: str | Path | None = None) -> Path:
    """Where automatic STHs are appended (JSON lines): $AUTHN_AUDIT_STH_LOG, else beside the key."""
    if explicit or os.environ.get(ENV_STH_LOG):
        return Path(explicit or os.environ[ENV_STH_LOG]).expanduser()
    return key_path(key).parent / "audit-sth.jsonl"


def key_id(public_raw: bytes) -> str:
    return hashlib.sha256(public_raw).hexdigest()


class LogKey:
    """A loaded Ed25519 private key (signs STHs) with its public half."""

    def __init__(self, private: Any, path: Path) -> None:
        from cryptography.hazmat.primitives import serialization

        self._private = private
        self.path = path
        self.public_key = private.public_key()
        self.public_raw = private.public_key().public_bytes(serialization.Encoding.Raw,
                                                            serialization.PublicFormat.Raw)
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
    def load(cls, path: str | Path | None = None, *, create: bool = True) -> "LogKey":
        """The key at `path` (see key_path), generated there on first use when `create`."""
        from cryptography.hazmat.primitives import serialization
        from cryptography.hazmat.primitives.asymmetric import ed25519

        p = key_path(path)
        if not p.exists():
            if not create:
                raise SystemFault(f"audit log key {p} does not exist (it is created by the first audit write)")
            _create(p)
        try:
            data = p.read_bytes()
        except OSError as exc:
            raise SystemFault(f"audit log key {p}: cannot read ({exc.strerror})") from None
        try:
            private = serialization.load_pem_private_key(data, password=None)
        except (ValueError, TypeError) as exc:
            raise SystemFault(f"audit log key {p}: not an unencrypted PEM private key ({exc})") from None
        if not isinstance(private, ed25519.Ed25519PrivateKey):
            raise SystemFault(f"audit log key {p}: not an Ed25519 key")
        return cls(private, p)

    def public_pem(self) -> str:
        from cryptography.hazmat.primitives import serialization

        return self._private.public_key().public_bytes(
            serialization.Encoding.PEM, serialization.PublicFormat.SubjectPublicKeyInfo).decode()

    def sign_tree_head(self, tree_size: int, root_hash: bytes, timestamp_ms: int) -> "SignedTreeHead":
        unsigned = SignedTreeHead(tree_size, timestamp_ms, root_hash.hex(), self.key_id, "")
        sig = base64.b64encode(self._private.sign(unsigned.signed_bytes())).decode()
        self._vouched.add((unsigned.signed_bytes(), sig))
        return SignedTreeHead(tree_size, timestamp_ms, root_hash.hex(), self.key_id, sig)


def _create(p: Path) -> None:
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


def load_public_key(path: str | Path) -> Any:
    """An Ed25519 public key from a PEM file (public key, or the private key itself)."""
    from cryptography.hazmat.primitives import serialization
    from cryptography.hazmat.primitives.asymmetric import ed25519

    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise AuthnError(f"{p}: cannot read public key ({exc.strerror})") from None
    try:
        key: Any = serialization.load_pem_public_key(data)
    except (ValueError, TypeError):
        try:
            key = serialization.load_pem_private_key(data, password=None).public_key()
        except (ValueError, TypeError):
            raise AuthnError(f"{p}: not a PEM Ed25519 public key") from None
    if not isinstance(key, ed25519.Ed25519PublicKey):
        raise AuthnError(f"{p}: not an Ed25519 key")
    return key


def public_raw(public_key: Any) -> bytes:
    from cryptography.hazmat.primitives import serialization

    return public_key.public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)


@dataclass(frozen=True)
class SignedTreeHead:
    tree_size: int
    timestamp: int  # ms since the epoch, UTC
    root_hash: str  # hex
    log_key_id: str  # hex SHA-256 of the raw public key
    signature: str  # base64 Ed25519

    @property
    def size(self) -> int:  # the old Checkpoint's name
        return self.tree_size

    @property
    def root(self) -> bytes:
        return bytes.fromhex(self.root_hash)

    def signed_bytes(self) -> bytes:
        return canonical_json({"format": STH_FORMAT, "tree_size": self.tree_size, "timestamp": self.timestamp,
                               "root_hash": self.root_hash, "log_key_id": self.log_key_id}).encode()

    def to_dict(self) -> dict[str, Any]:
        return {"format": STH_FORMAT, "tree_size": self.tree_size, "timestamp": self.timestamp,
                "root_hash": self.root_hash, "log_key_id": self.log_key_id, "signature": self.signature}

    def to_json(self) -> str:
        return canonical_json(self.to_dict())

    @classmethod
    def from_dict(cls, doc: Any, what: str = "signed tree head") -> "SignedTreeHead":
        try:
            if not isinstance(doc, dict) or doc.get("format") != STH_FORMAT:
                raise ValueError
            size, ts = doc["tree_size"], doc["timestamp"]
            root, kid, sig = doc["root_hash"], doc["log_key_id"], doc["signature"]
            if not (type(size) is int and type(ts) is int and size >= 0 and ts >= 0):
                raise ValueError
            if not all(isinstance(x, str) for x in (root, kid, sig)):
                raise ValueError
            if len(bytes.fromhex(root)) != 32 or len(bytes.fromhex(kid)) != 32 or root != root.lower() \
                    or kid != kid.lower():
                raise ValueError
            if len(base64.b64decode(sig, validate=True)) != 64:
                raise ValueError
        except (ValueError, KeyError, TypeError, binascii.Error):
            raise AuthnError(f"{what}: not an {STH_FORMAT} document") from None
        return cls(size, ts, root, kid, sig)

    @classmethod
    def from_json(cls, text: str | bytes, what: str = "signed tree head") -> "SignedTreeHead":
        try:
            if isinstance(text, bytes):
                text = text.decode("utf-8")
            doc = json.loads(text)
        except (UnicodeDecodeError, ValueError):
            raise AuthnError(f"{what}: not an {STH_FORMAT} JSON document") from None
        return cls.from_dict(doc, what)

    @classmethod
    def read(cls, path: str | Path) -> "SignedTreeHead":
        p = Path(path)
        try:
            data = p.read_bytes()
        except OSError as exc:
            raise AuthnError(f"{p}: cannot read signed tree head ({exc.strerror})") from None
        return cls.from_json(data, str(p))

    def verify_signature(self, public_key: Any) -> bool:
        """Whether the signature is the log key's over these fields (and the key id matches)."""
        from cryptography.exceptions import InvalidSignature

        if key_id(public_raw(public_key)) != self.log_key_id:
            return False
        try:
            public_key.verify(base64.b64decode(self.signature), self.signed_bytes())
        except InvalidSignature:
            return False
        return True


def read_sth_log(path: Path) -> list[tuple[str | None, SignedTreeHead]]:
    """Every well-formed STH line of an external STH file (a missing file is an empty list).

    Lines carry the STH fields plus "db" (which database they vouch for); lines that do
    not parse are skipped here and counted by the caller's checks of the ones that do."""
    try:
        lines = path.read_bytes().splitlines()
    except FileNotFoundError:
        return []
    except OSError as exc:
        raise SystemFault(f"{path}: cannot read the STH log ({exc.strerror})") from None
    out: list[tuple[str | None, SignedTreeHead]] = []
    for line in lines:
        try:
            doc = json.loads(line.decode("utf-8"))
            out.append((doc.get("db"), SignedTreeHead.from_dict({k: v for k, v in doc.items() if k != "db"})))
        except (UnicodeDecodeError, ValueError, AuthnError, AttributeError):
            continue
    return out


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
        doc = json.loads(text.decode("utf-8"))
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
