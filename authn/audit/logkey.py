"""The audit log's Ed25519 signing key: its file, its path, its retired keys.

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

The heads it signs are `authn.audit.tree_head`'s; the files that keep them,
`authn.audit.head_files`. `cryptography` is imported only when a key is loaded.
"""

from __future__ import annotations

import base64
import os
from pathlib import Path
from typing import TYPE_CHECKING

from core.errors import AuthnError, SystemFault
from core.pem import PemError, private_key, public_key, raw_public
from core.settings import current

from authn.audit.tree_head import SignedTreeHead, check_origin, key_id, note_key_hash


if TYPE_CHECKING:
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey, Ed25519PublicKey


def default_key_path() -> Path:
    from platformdirs import user_data_dir

    return Path(user_data_dir("authn")) / "audit-log-key.pem"


def key_path(explicit: str | Path | None = None) -> Path:
    """--log-key, else $AUTHN_LOG_KEY, else the user data directory."""
    return Path(explicit or current().log_key or default_key_path()).expanduser()


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




