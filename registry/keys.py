"""Ed25519 public keys from files: 32 raw bytes, 64 hex digits, or PEM.

A PEM Ed25519 public key is a fixed 44-byte SubjectPublicKeyInfo, so it is
parsed here without a crypto library (none is needed to store a key).
"""

from __future__ import annotations

import base64
import binascii
import re
from pathlib import Path

from registry.errors import RegistryError

_SPKI_ED25519_PREFIX = bytes.fromhex("302a300506032b6570032100")
_PEM = re.compile(rb"-----BEGIN PUBLIC KEY-----(.*?)-----END PUBLIC KEY-----", re.S)


def parse_public_key(data: bytes, source: str = "public key") -> bytes:
    """The 32 raw key bytes, or RegistryError naming what is wrong."""
    if len(data) == 32 and not re.fullmatch(rb"[0-9a-fA-F\s]+", data):
        return data
    m = _PEM.search(data)
    if m:
        try:
            der = base64.b64decode(b"".join(m.group(1).split()), validate=True)
        except binascii.Error:
            raise RegistryError(f"{source}: PEM body is not base64") from None
        if len(der) != 44 or not der.startswith(_SPKI_ED25519_PREFIX):
            raise RegistryError(f"{source}: PEM key is not an Ed25519 public key")
        return der[12:]
    text = data.strip()
    if re.fullmatch(rb"[0-9a-fA-F]{64}", text):
        return bytes.fromhex(text.decode())
    if len(data) == 32:
        return data
    raise RegistryError(f"{source}: expected 32 raw bytes, 64 hex digits or an Ed25519 PEM key")


def read_public_key(path: str | Path) -> bytes:
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise RegistryError(f"{path}: cannot read public key ({exc.strerror})") from None
    return parse_public_key(data, str(path))
