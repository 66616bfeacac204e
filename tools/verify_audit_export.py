#!/usr/bin/env python3
"""Verify an `authn audit export --dir` folder without authn: the standard library and
`cryptography` only. Recomputes the RFC 9162 Merkle root from the leaf bytes (leaves.jsonl),
checks the chain each entry names, the checkpoint's Ed25519 signature (C2SP signed note) by
log-key.pub.pem, and its size and root. Encodings: docs/audit.md ("Leaf bytes", "Export").

Usage: verify_audit_export.py DIR    exit 0 verified, 1 not (one line either way)
"""

import base64
import hashlib
import json
import sys
from pathlib import Path

from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey
from cryptography.hazmat.primitives.serialization import Encoding, PublicFormat, load_pem_public_key


def sha256(data: bytes) -> bytes:
    return hashlib.sha256(data).digest()


def tree_root(leaves: list[bytes]) -> bytes:
    """RFC 9162 MTH over leaf hashes: the left subtree holds the largest power of two < n."""
    if len(leaves) < 2:
        return leaves[0] if leaves else sha256(b"")
    k = 1 << ((len(leaves) - 1).bit_length() - 1)
    return sha256(b"\x01" + tree_root(leaves[:k]) + tree_root(leaves[k:]))


def read_leaves(path: Path) -> list[bytes]:
    """Each entry's leaf hash, after checking its position and the chain its bytes name."""
    hashes, prev = [], "0" * 64
    for n, line in enumerate(path.read_text(encoding="ascii").splitlines(), start=1):
        record = json.loads(line)
        body = base64.b64decode(record["leaf"], validate=True)
        if body[:1] not in (b"\x01", b"{"):
            raise ValueError(f"entry {n}: leaf bytes in no known encoding")
        entry = json.loads(body[1:] if body[:1] == b"\x01" else body)
        if record["seq"] != n or entry["seq"] != n:
            raise ValueError(f"entry {n}: out of place")
        if entry["prev_hash"] != prev:
            raise ValueError(f"entry {n} does not link to entry {n - 1}")
        prev = hashlib.sha256(body).hexdigest()
        hashes.append(sha256(b"\x00" + body))
    return hashes


def check_signature(note: str, key: Ed25519PublicKey) -> tuple[int, bytes]:
    """The checkpoint's (size, root) when a signature line is this key's over its body."""
    body, _, signatures = note.partition("\n\n")
    origin, size, root = body.split("\n")[:3]
    raw = key.public_bytes(Encoding.Raw, PublicFormat.Raw)
    key_hash = sha256(origin.encode() + b"\n\x01" + raw)[:4]
    for line in signatures.splitlines():
        parts = line.split(" ")
        if len(parts) != 3 or parts[0] != "\u2014" or parts[1] != origin:
            continue
        sig = base64.b64decode(parts[2], validate=True)
        try:
            if sig[:4] == key_hash:
                key.verify(sig[4:], (body + "\n").encode())
                return int(size), base64.b64decode(root, validate=True)
        except InvalidSignature:
            continue
    raise ValueError("the checkpoint carries no valid signature by this public key")


def verify(folder: Path) -> str:
    key = load_pem_public_key((folder / "log-key.pub.pem").read_bytes())
    if not isinstance(key, Ed25519PublicKey):
        raise ValueError("log-key.pub.pem is not an Ed25519 public key")
    size, root = check_signature((folder / "checkpoint.txt").read_text(encoding="utf-8"), key)
    leaves = read_leaves(folder / "leaves.jsonl")
    if len(leaves) != size:
        raise ValueError(f"{len(leaves)} entries, but the checkpoint signed {size}")
    if tree_root(leaves) != root:
        raise ValueError("the entries do not make the tree root the checkpoint signed")
    return f"OK: {size} entries, tree root {root.hex()}, checkpoint signed by the given key"


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print("usage: verify_audit_export.py DIR", file=sys.stderr)
        return 1
    try:
        print(verify(Path(argv[1])))
    except (OSError, ValueError, KeyError, TypeError, IndexError, RecursionError) as exc:
        print(f"FAILED: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
