"""UA signing keys for DRIP (RFC 9374/9575): generate, store, load, name by DET.

The drone's side of Remote ID authentication, used by `authn keys generate` and by the
simulator to sign what a simulated drone broadcasts. The registry stores only the public
half (`authn register --public-key`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from core.errors import BadInput

__all__ = ["DEFAULT_RAA", "DEFAULT_HDA", "UaKey", "det_of", "generate", "load", "load_trusted_registries",
           "read_public_key_arg"]

#: The Registered Assigning Authority and HDA put in generated DETs (RFC 9374 HID). RAA
#: 16376 lies in the range RFC 9374 leaves for experiments; real deployments take theirs
#: from their registry.
DEFAULT_RAA, DEFAULT_HDA = 16376, 1


@dataclass(frozen=True)
class UaKey:
    """An Ed25519 key pair and the DET that names it."""

    private_raw: bytes
    public_raw: bytes
    det: bytes

    @property
    def session_id(self) -> str:
        return session_id_of(self.det)


def session_id_of(det: bytes) -> str:
    """The UAS ID of a DRIP identity: Specific Session ID type 1 (IETF DRIP) + the DET, as
    hex (what Basic ID type 4 broadcasts and what `authn register --id-type specific_session` takes)."""
    return ("01" + det.hex()).upper()


def _det(public_raw: bytes, raa: int, hda: int) -> bytes:
    from remoteid.drip import det_from_public_key

    if not (0 <= raa < 1 << 14 and 0 <= hda < 1 << 14):
        raise BadInput(f"RAA and HDA are 14-bit numbers (0..16383), got {raa} and {hda}")
    return det_from_public_key(public_raw, raa, hda)


def det_of(public_raw: bytes, raa: int = DEFAULT_RAA, hda: int = DEFAULT_HDA) -> bytes:
    """The DET (RFC 9374) of an Ed25519 public key: what `authn keys show` prints."""
    return _det(public_raw, raa, hda)


def read_public_key_arg(value: str) -> bytes:
    """A `--public-key` argument: a key file (PEM, 32 raw bytes or 64 hex digits, as `authn register`
    reads) or, when no such file exists, the 64 hex digits themselves (a raw Ed25519 key)."""
    import re

    from registry.keys import read_public_key

    text = str(value).strip()
    if re.fullmatch(r"[0-9A-Fa-f]{64}", text) and not Path(value).exists():
        return bytes.fromhex(text)
    return read_public_key(value)


def generate(raa: int = DEFAULT_RAA, hda: int = DEFAULT_HDA) -> UaKey:
    from cryptography.hazmat.primitives import serialization
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

    key = Ed25519PrivateKey.generate()
    private = key.private_bytes(serialization.Encoding.Raw, serialization.PrivateFormat.Raw,
                                serialization.NoEncryption())
    public = key.public_key().public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)
    return UaKey(private, public, _det(public, raa, hda))


def write(key: UaKey, path: Path) -> tuple[Path, Path]:
    """The private key as PKCS#8 PEM (mode 0600) and the public key beside it (`.pub.pem`)."""
    from cryptography.hazmat.primitives import serialization
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

    private = Ed25519PrivateKey.from_private_bytes(key.private_raw)
    pem = private.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                serialization.NoEncryption())
    pub_pem = private.public_key().public_bytes(serialization.Encoding.PEM,
                                                serialization.PublicFormat.SubjectPublicKeyInfo)
    public_path = path.with_name(path.name.removesuffix(".pem") + ".pub.pem")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(fd, "wb") as fh:
            fh.write(pem)
        public_path.write_bytes(pub_pem)
    except FileExistsError:
        raise BadInput(f"{path}: exists; choose another --out (keys are never overwritten)") from None
    except OSError as exc:
        raise BadInput(f"{path}: cannot write the key ({exc.strerror})") from None
    return path, public_path


def load(path: Path, raa: int = DEFAULT_RAA, hda: int = DEFAULT_HDA) -> UaKey:
    """A private key written by `write` (PKCS#8 PEM, unencrypted)."""
    from cryptography.hazmat.primitives import serialization

    from core.pem import PemError, private_key, raw_public

    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise BadInput(f"{path}: cannot read the signing key ({exc.strerror})") from None
    try:
        private = private_key(data)
    except PemError as exc:
        raise BadInput(f"{path}: not an unencrypted PEM private key" if exc.kind == "pem" else
                       f"{path}: not an Ed25519 key") from None
    raw = private.private_bytes(serialization.Encoding.Raw, serialization.PrivateFormat.Raw,
                                serialization.NoEncryption())
    public = raw_public(private.public_key())
    return UaKey(raw, public, _det(public, raa, hda))


def load_trusted_registries(path: Path) -> dict[bytes, bytes]:
    """Registries (HDAs) whose DRIP Links the site trusts: a JSON file
    `{"registries": [{"det": "<HDA DET, hex or IPv6 text>", "public_key": "<64 hex digits>"}]}`."""
    from core.parsing import JsonTooDeep, loads_json
    from remoteid.drip import DripError, parse_det

    try:
        doc = loads_json(Path(path).read_text())
        entries = doc["registries"]
        if not isinstance(entries, list):
            raise TypeError
    except OSError as exc:
        raise BadInput(f"{path}: cannot read trusted registries ({exc.strerror})") from None
    except JsonTooDeep as exc:
        raise BadInput(f"{path}: {exc}") from None
    except (ValueError, KeyError, TypeError, AttributeError):
        raise BadInput(f'{path}: expected {{"registries": [{{"det": ..., "public_key": ...}}]}}') from None
    out: dict[bytes, bytes] = {}
    for i, entry in enumerate(entries):
        try:
            key = bytes.fromhex(str(entry["public_key"]))
            if len(key) != 32:
                raise ValueError
            out[parse_det(str(entry["det"]))] = key
        except (KeyError, TypeError, ValueError, DripError):
            raise BadInput(f"{path}: registries[{i}]: needs a DET and a 32-byte public key (hex)") from None
    return out
