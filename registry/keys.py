"""Ed25519 public keys from files: 32 raw bytes, 64 hex digits, or PEM (parsed by
`core.pem`, the product's one PEM parser)."""

from __future__ import annotations

import re
from pathlib import Path

from registry.errors import RegistryError

_PEM_PUBLIC = b"-----BEGIN PUBLIC KEY-----"


def parse_public_key(data: bytes, source: str = "public key") -> bytes:
    """The 32 raw key bytes, or RegistryError naming what is wrong."""
    if len(data) == 32 and not re.fullmatch(rb"[0-9a-fA-F\s]+", data):
        return data
    if _PEM_PUBLIC in data:
        from core.pem import PemError, public_key, raw_public

        try:
            return raw_public(public_key(data))
        except PemError as exc:
            what = "is not a readable PEM public key" if exc.kind == "pem" else "is not an Ed25519 public key"
            raise RegistryError(f"{source}: PEM key {what}") from None
    text = data.strip()
    if re.fullmatch(rb"[0-9a-fA-F]{64}", text):
        return bytes.fromhex(text.decode())
    if len(data) == 32:
        return data
    raise RegistryError(f"{source}: expected 32 raw bytes, 64 hex digits or an Ed25519 PEM key")


def read_public_key(path: str | Path) -> bytes:
    """The key in the file at `path` (see `parse_public_key`)."""
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise RegistryError(f"{path}: cannot read public key ({exc.strerror})") from None
    return parse_public_key(data, str(path))
