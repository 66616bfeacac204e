"""DRIP verification (RFC 9575): Authentication pages -> signed structures -> one AuthResult.

`verify` never raises on recorded data: malformed pages or structures become `invalid`
with a one-line reason. `cryptography` (Ed25519) is imported only when authentication
pages exist.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from datetime import datetime

from registry.remoteid.drip_formats import (
    AUTH_TYPE_SAM,
    PAGE0_DATA,
    PAGE_DATA,
    SAM_FRAME,
    SAM_MANIFEST,
    SAM_WRAPPER,
    DripError,
    Link,
    det_matches_key,
    length_fits,
    message_hash,
    parse_sam,
    to_drip_time,
)
from registry.remoteid.errors import RemoteIdError
from registry.remoteid.messages import AuthPage, AuthPage0, BasicId, Location

STATUSES = ("valid", "invalid", "absent", "unknown-key", "expired")


@dataclass(frozen=True)
class AuthMessage:
    """One reassembled authentication message: its bytes, or why it is malformed."""

    auth_type: int
    timestamp: datetime | None
    data: bytes | None = None
    reason: str | None = None


@dataclass(frozen=True)
class AuthResult:
    """The DRIP verdict of one recording.

    status: valid / invalid / absent / unknown-key / expired; reason: one line (for all but
    a plain valid or absent); sam_types: the DRIP SAM types that verified ("link",
    "wrapper", "manifest", "frame"); covered: indices (into the messages given to
    `verify`) of the Basic ID and Location messages that a verified Wrapper or Manifest
    covers; det: the UA's DET (hex) that signed, or the first DET seen.
    """

    status: str
    reason: str | None = None
    sam_types: tuple[str, ...] = ()
    covered: tuple[int, ...] = ()
    det: str | None = None
    details: tuple[str, ...] = field(default=(), compare=False)

    def to_dict(self) -> dict:
        return {"status": self.status, "reason": self.reason, "sam_types": list(self.sam_types),
                "covered": list(self.covered), "det": self.det}


# ------------------------------------------------------------------ reassembly
class _Open:
    __slots__ = ("page0", "pages", "conflict")

    def __init__(self, page0: AuthPage0):
        self.page0 = page0
        self.pages: dict[int, bytes] = {0: page0.data}
        self.conflict: str | None = None


def reassemble(messages: Iterable) -> list[AuthMessage]:
    """Authentication pages (AuthPage0 / AuthPage, other messages ignored) -> messages.

    A page 0 opens (or, repeated identically, re-opens) a message of its auth type; pages
    1..15 join the message of their auth type that the latest page 0 opened, so messages
    sent one after another, repeated or interleaved with other auth types reassemble.
    Missing pages, a page past the last index, the same page with other bytes, or a
    length impossible for the last page index make that message malformed.
    """
    order: list[_Open] = []
    by_key: dict[tuple, _Open] = {}
    current: dict[int, _Open] = {}
    orphans: list[AuthMessage] = []
    for m in messages:
        if isinstance(m, AuthPage0):
            key = (m.auth_type, m.last_page_index, m.length, m.timestamp, m.data)
            rec = by_key.get(key)
            if rec is None:
                rec = by_key[key] = _Open(m)
                order.append(rec)
            current[m.auth_type] = rec
        elif isinstance(m, AuthPage):
            rec = current.get(m.auth_type)
            if rec is None:
                orphans.append(AuthMessage(m.auth_type, None, reason=(
                    f"auth type {m.auth_type}: page {m.page} without a page 0")))
                continue
            last = rec.page0.last_page_index
            if m.page > last:
                rec.conflict = rec.conflict or (
                    f"auth type {m.auth_type}: page {m.page} past the last page index {last}")
                continue
            seen = rec.pages.get(m.page)
            if seen is not None and seen != m.data:
                rec.conflict = rec.conflict or (
                    f"auth type {m.auth_type}: page {m.page} seen twice with different bytes")
                continue
            rec.pages[m.page] = m.data
    out = [_close(rec) for rec in order]
    return out + orphans


def _close(rec: _Open) -> AuthMessage:
    p0 = rec.page0
    t, ts, last, length = p0.auth_type, p0.timestamp, p0.last_page_index, p0.length
    if rec.conflict:
        return AuthMessage(t, ts, reason=rec.conflict)
    if not length_fits(length, last):
        hi = PAGE0_DATA + PAGE_DATA * last
        return AuthMessage(t, ts, reason=(
            f"auth type {t}: length {length} impossible for last page index {last} (max {hi})"))
    missing = [k for k in range(last + 1) if k not in rec.pages]
    if missing:
        return AuthMessage(t, ts, reason=(
            f"auth type {t}: page{'s' if len(missing) > 1 else ''} "
            f"{', '.join(map(str, missing))} of 0..{last} missing"))
    data = b"".join(rec.pages[k] for k in range(last + 1))[:length]
    return AuthMessage(t, ts, data=data)


# ------------------------------------------------------------------ verification
def _split(item) -> tuple[object, bytes | None]:
    """A decoded message, 25 raw bytes or a (message, raw) pair -> (message, raw)."""
    if isinstance(item, tuple) and len(item) == 2:
        return item[0], bytes(item[1])
    if isinstance(item, (bytes, bytearray, memoryview)):
        from registry.remoteid.codec import decode

        raw = bytes(item)
        try:
            return decode(raw), raw
        except RemoteIdError:
            return None, raw
    return item, None


def _raw_of(msg, raw: bytes | None) -> bytes | None:
    if raw is not None:
        return raw
    if msg is None:
        return None
    from registry.remoteid.codec import encode

    try:
        return encode(msg)
    except RemoteIdError:
        return None


def verify(messages: Iterable, key_for: Callable[[bytes], bytes | None], dwell_time: datetime, *,
           trusted_registry_keys: Mapping[bytes, bytes] = {}, skew_s: float = 5.0) -> AuthResult:
    """DRIP authentication of one recording's flattened Remote ID messages.

    `messages` holds decoded messages, raw 25-byte messages or (message, raw) pairs (see
    `codec.decode_rows_raw`); without raw bytes a message is re-encoded, which equals the
    wire form for canonical senders only. `key_for(det)` is the registry's Ed25519 key for
    a UA DET; a DRIP Link that verifies under `trusted_registry_keys[hda_det]` (and whose
    UA DET is the DET of the UA key it carries) also supplies the UA's key.
    """
    items = [_split(m) for m in messages]
    decoded = [m for m, _ in items]
    if not any(isinstance(m, (AuthPage0, AuthPage)) for m in decoded):
        return AuthResult("absent")
    try:
        return _verify(items, decoded, key_for, dwell_time, trusted_registry_keys, skew_s)
    except (DripError, RemoteIdError, ValueError, TypeError) as exc:  # e.g. a dwell time before 2019
        return AuthResult("invalid", reason=str(exc).splitlines()[0] if str(exc) else type(exc).__name__)


def _verify(items, decoded, key_for, dwell_time, trusted, skew_s) -> AuthResult:
    from cryptography.exceptions import InvalidSignature
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey

    def sig_ok(key: bytes, sig: bytes, data: bytes) -> bool:
        try:
            Ed25519PublicKey.from_public_bytes(bytes(key)).verify(sig, data)
            return True
        except (InvalidSignature, ValueError):
            return False

    now = to_drip_time(dwell_time) if dwell_time.tzinfo else None
    if now is None:
        return AuthResult("invalid", reason="dwell time must be timezone-aware")

    def in_window(s) -> bool:
        return s.vnb - skew_s <= now <= s.vna + skew_s

    structures = []
    others = set()
    for am in reassemble(decoded):
        if am.reason:
            return AuthResult("invalid", reason=am.reason)
        if am.auth_type != AUTH_TYPE_SAM:
            others.add(am.auth_type)
            continue
        try:
            structures.append(parse_sam(am.data))
        except DripError as exc:
            return AuthResult("invalid", reason=str(exc))
    if not structures:
        kinds = ", ".join(str(t) for t in sorted(others))
        return AuthResult("absent", reason=f"authentication type {kinds} is not DRIP (not checked)")

    # Subjects a signature may cover: the non-authentication messages actually decoded.
    subjects: dict[bytes, list[int]] = {}
    hashes: dict[bytes, list[int]] = {}
    for i, (m, raw) in enumerate(items):
        if m is None or isinstance(m, (AuthPage0, AuthPage)):
            continue
        raw = _raw_of(m, raw)
        if raw is None:
            continue
        subjects.setdefault(raw, []).append(i)
        hashes.setdefault(message_hash(raw), []).append(i)

    def coverable(idx: list[int]) -> list[int]:
        return [i for i in idx if isinstance(decoded[i], (BasicId, Location))]

    learned: dict[bytes, bytes] = {}
    verified: list[str] = []
    covered: set[int] = set()
    unknown: list[str] = []
    expired: list[str] = []
    det_hex = structures[0].det.hex()
    signer_det = None
    for s in sorted(structures, key=lambda s: not isinstance(s, Link)):
        if isinstance(s, Link):
            hda_key = trusted.get(s.hda_det)
            if hda_key is None:
                unknown.append(f"DRIP link: HDA {s.hda_det.hex()} is not a trusted registry")
                continue
            if not sig_ok(hda_key, s.signature, s.signed_bytes):
                return AuthResult("invalid", reason="DRIP link: HDA signature does not verify",
                                  det=s.ua_det.hex())
            if not det_matches_key(s.ua_det, s.ua_key):
                return AuthResult("invalid", reason="DRIP link: UA DET is not the DET of the UA key it carries",
                                  det=s.ua_det.hex())
            if not in_window(s):
                expired.append(f"DRIP link valid {s.vnb}..{s.vna}, dwell time {now} (s since 2019)")
                continue
            learned[s.ua_det] = s.ua_key
            verified.append("link")
            continue
        key = key_for(s.det) if key_for is not None else None
        key = key or learned.get(s.det)
        if key is None:
            unknown.append(f"DRIP {s.name}: no key for DET {s.det.hex()}")
            continue
        if not sig_ok(key, s.signature, s.signed_bytes):
            return AuthResult("invalid", reason=f"DRIP {s.name}: signature does not verify",
                              det=s.det.hex())
        if not in_window(s):
            expired.append(f"DRIP {s.name} valid {s.vnb}..{s.vna}, dwell time {now} (s since 2019)")
            continue
        carried = s.wrapped() if s.sam_type == SAM_WRAPPER else \
            s.frame_messages() if s.sam_type == SAM_FRAME else None
        if carried is not None:  # a Wrapper's messages, or a Frame of F3411 messages
            for k, w in enumerate(carried):
                idx = subjects.get(w)
                if not idx:
                    return AuthResult("invalid", det=s.det.hex(), reason=(
                        f"DRIP {s.name}: signed message {k + 1} (type 0x{w[0] >> 4:X}) "
                        "is not among the decoded messages"))
                covered.update(coverable(idx))
        elif s.sam_type == SAM_MANIFEST:
            if not s.manifest_current_ok():
                return AuthResult("invalid", det=s.det.hex(),
                                  reason="DRIP manifest: current manifest hash does not match its evidence")
            for h in s.manifest_hashes()[3]:
                covered.update(coverable(hashes.get(h, [])))
        verified.append(s.name)
        signer_det = signer_det or s.det.hex()

    det_hex = signer_det or det_hex
    if expired:
        return AuthResult("expired", reason=expired[0], sam_types=tuple(dict.fromkeys(verified)),
                          det=det_hex, details=tuple(expired + unknown))
    if verified:
        return AuthResult("valid", sam_types=tuple(dict.fromkeys(verified)), covered=tuple(sorted(covered)),
                          det=det_hex, details=tuple(unknown))
    return AuthResult("unknown-key", reason=unknown[0], det=det_hex, details=tuple(unknown))
