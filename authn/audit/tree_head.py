"""The audit log's signed tree heads: C2SP checkpoints (https://c2sp.org/tlog-checkpoint) whose
origin line names the log, so a head of one log never verifies for another signed with the same
key; heads written before origins existed (authn-sth/1 JSON, no origin) still verify. The key
that signs them is `authn.audit.logkey`; the files that keep them, `authn.audit.head_files`.
`cryptography` is imported only when a signature is checked.
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from core.errors import AuthnError
from core.parsing import loads_json
from core.pem import raw_public

if TYPE_CHECKING:
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey

STH_FORMAT = "authn-sth/1"  # legacy heads: JSON, no origin
CHECKPOINT_FORMAT = "authn-checkpoint/1"  # JSON carrying a C2SP checkpoint and its fields
TIMESTAMP_EXTENSION = "authn-timestamp-ms"


def canonical_json(obj: object) -> str:
    """One byte-exact encoding: sorted keys, no spaces, UTF-8, finite numbers only."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)


def key_id(public_raw: bytes) -> str:
    return hashlib.sha256(public_raw).hexdigest()


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

