"""Ed25519 keys from PEM, parsed by `cryptography` (the product's one PEM parser).

Each caller turns `PemError` into its own error (a registry entry, a log key, a UA key), so
the wording of its message stays the caller's; `cryptography` is imported only here, inside
the functions, because a cold check never reads a key file.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey, Ed25519PublicKey

__all__ = ["PemError", "private_key", "public_key", "raw_public"]


class PemError(ValueError):
    """Not a PEM key (`kind` 'pem') or a PEM key of another algorithm (`kind` 'algorithm')."""

    def __init__(self, kind: str) -> None:
        super().__init__("not a PEM key" if kind == "pem" else "not an Ed25519 key")
        self.kind = kind


def public_key(data: bytes, *, private_ok: bool = False) -> Ed25519PublicKey:
    """The Ed25519 public key of a PEM public key (or, with `private_ok`, of an unencrypted
    PEM private key: its public half)."""
    from cryptography.hazmat.primitives import serialization
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey

    key: object
    try:
        key = serialization.load_pem_public_key(data)
    except (ValueError, TypeError, UnicodeDecodeError):
        if not private_ok:
            raise PemError("pem") from None
        key = private_key(data).public_key()
    if not isinstance(key, Ed25519PublicKey):
        raise PemError("algorithm")
    return key


def private_key(data: bytes) -> Ed25519PrivateKey:
    """The Ed25519 key of an unencrypted PEM (PKCS#8) private key."""
    from cryptography.hazmat.primitives import serialization
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

    try:
        key = serialization.load_pem_private_key(data, password=None)
    except (ValueError, TypeError, UnicodeDecodeError):
        raise PemError("pem") from None
    if not isinstance(key, Ed25519PrivateKey):
        raise PemError("algorithm")
    return key


def raw_public(key: Ed25519PublicKey) -> bytes:
    """The 32 raw bytes of a public key (RFC 8032), what the registry stores."""
    from cryptography.hazmat.primitives import serialization

    return key.public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)
