"""Model cards: what a shipped model bundle is, and proof that its files are the ones trained.

A bundle is a folder: `card.json` plus the model files it lists. The card records
the profiles, preset, training seed and size, metrics, library versions and the
SHA-256 of every file. Loading recomputes the digests and refuses any mismatch, so a
swapped or corrupted model cannot silently decide an authentication. Only json and
hashlib here: the check path must not pull in sklearn or torch.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

from core.digest import file_sha256
from core.parsing import JsonTooDeep, loads_json
from signatures.errors import SignaturesError

__all__ = ["CARD_FORMAT", "CARD_NAME", "ModelIntegrityError", "card_bytes", "library_versions", "read_card",
           "write_card"]

CARD_NAME = "card.json"
CARD_FORMAT = "uav-radar-authn/model-bundle/1"


class ModelIntegrityError(SignaturesError):
    """A model bundle whose files do not match its card (tampered, corrupted, incomplete)."""


def card_bytes(card: dict[str, Any]) -> bytes:
    """Canonical serialisation (sorted keys, fixed indent): rebuilds give identical bytes."""
    return (json.dumps(card, sort_keys=True, indent=1, allow_nan=False) + "\n").encode()


def write_card(folder: Path, card: dict[str, Any]) -> str:
    """Add the digests of the files named in `card["files"]`, write card.json, return its digest."""
    card = dict(card, format=CARD_FORMAT)
    card["files"] = {name: file_sha256(folder / name) for name in sorted(card["files"])}
    data = card_bytes(card)
    (folder / CARD_NAME).write_bytes(data)
    return hashlib.sha256(data).hexdigest()


def read_card(folder: Path) -> tuple[dict[str, Any], str]:
    """Read and verify a bundle: returns (card, SHA-256 of card.json); raises on any mismatch."""
    path = folder / CARD_NAME
    try:
        data = path.read_bytes()
        card = loads_json(data)
    except OSError as exc:
        raise ModelIntegrityError(f"{path}: cannot read model card ({exc.strerror})") from None
    except JsonTooDeep as exc:
        raise ModelIntegrityError(f"{path}: model card: {exc}") from None
    except json.JSONDecodeError as exc:
        raise ModelIntegrityError(f"{path}: model card is not JSON ({exc.msg})") from None
    if not isinstance(card, dict) or card.get("format") != CARD_FORMAT or not isinstance(card.get("files"), dict):
        raise ModelIntegrityError(f"{path}: not a {CARD_FORMAT} model card")
    for name, expected in card["files"].items():
        f = folder / name
        if not f.is_file():
            raise ModelIntegrityError(f"{f}: model file listed in its card is missing")
        actual = file_sha256(f)
        if actual != expected:
            raise ModelIntegrityError(
                f"{f}: SHA-256 {actual[:16]}... does not match its model card ({expected[:16]}...); "
                "refusing to load a modified model (rebuild with `authn models train`)")
    return card, hashlib.sha256(data).hexdigest()


def library_versions() -> dict[str, str]:
    """Versions of the libraries that produced a bundle (those importable now)."""
    import importlib.metadata as md

    out = {}
    for name in ("numpy", "scikit-learn", "onnx", "onnxruntime", "torch"):
        try:
            out[name] = md.version(name)
        except md.PackageNotFoundError:
            pass
    return out
