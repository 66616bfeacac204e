"""The leaf bytes of an audit entry: what is stored (`audit_log.leaf_bytes`) and hashed.

An entry's Merkle leaf hash is SHA-256(0x00 || leaf bytes) (RFC 6962/9162) and its chain
hash (`entry_hash`) SHA-256(leaf bytes). The bytes are written once, at append, and read
back as stored; the other columns are a readable copy that must agree with them. Two
encodings, told apart by the first byte (docs/audit.md, "Leaf bytes"):

    0x01  version 1: 0x01 || canonical JSON of the object {created_at, decision, kind,
          payload, prev_hash, seq, serial}; payload is the entry's JSON object itself;
          created_at is "YYYY-MM-DDTHH:MM:SS.ffffffZ" (UTC, six fractional digits).
    0x7b  version 0 ('{', entries written before revision 0008): canonical JSON of the
          same keys with payload as a JSON string holding its canonical text and
          created_at as "YYYY-MM-DDTHH:MM:SS.ffffff+00:00".

Canonical JSON: UTF-8, object keys sorted by code point, no whitespace, non-ASCII as is,
no NaN or infinities (Python's json with sort_keys, separators (",", ":"),
ensure_ascii=False, allow_nan=False).
"""

from __future__ import annotations

import json
from datetime import datetime, timezone

VERSION = 1
_V1 = b"\x01"
_ENC = json.JSONEncoder(sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)
_S = _ENC.encode


def time_text(when: datetime) -> str:
    """created_at as version 1 writes it: UTC, microseconds, 'Z'."""
    return when.astimezone(timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def encode(seq: int, created: str, kind: str, serial: str | None, decision: str | None, payload: str,
           prev_hash: str) -> bytes:
    """Version 1 leaf bytes; `created` as time_text writes it, `payload` the canonical JSON
    text of the payload object (inlined as is: its text is already canonical)."""
    return _V1 + (f'{{"created_at":{_S(created)},"decision":{_S(decision)},"kind":{_S(kind)},'
                  f'"payload":{payload},"prev_hash":{_S(prev_hash)},"seq":{int(seq)},'
                  f'"serial":{_S(serial)}}}').encode("utf-8")


def encode_v0(seq: int, created: str, kind: str, serial: str | None, decision: str | None, payload: str,
              prev_hash: str) -> bytes:
    """Version 0 leaf bytes (`created` with '+00:00'): the entries of a log from before 0008."""
    return _S({"seq": seq, "created_at": created, "kind": kind, "serial": serial, "decision": decision,
               "payload": payload, "prev_hash": prev_hash}).encode("utf-8")


def version(leaf: bytes) -> int | None:
    """The encoding of stored leaf bytes (None: neither)."""
    return 1 if leaf[:1] == _V1 else 0 if leaf[:1] == b"{" else None
