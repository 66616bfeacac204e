"""DRIP verification (RFC 9575): Authentication pages -> signed structures -> one AuthResult.

`verify` never raises on recorded data: malformed pages or structures become `invalid`
with a one-line reason. `cryptography` (Ed25519) is imported only when authentication
pages exist.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from datetime import datetime, timezone
from typing import TYPE_CHECKING

from remoteid.drip_formats import (
    AUTH_TYPE_SAM,
    PAGE0_DATA,
    PAGE_DATA,
    SAM_FRAME,
    SAM_MANIFEST,
    SAM_WRAPPER,
    DripError,
    Link,
    det_matches_key,
    from_drip_time,
    has_fec_page,
    length_fits,
    message_hash,
    parse_sam,
    valid_time_text,
    xor_pages,
)
from remoteid.errors import RemoteIdError
from remoteid.messages import ODID_EPOCH, AuthPage, AuthPage0, BasicId, Location

if TYPE_CHECKING:
    from remoteid.drip_formats import Signed
    from remoteid.messages import Message

    #: what `verify` takes per message: the decoded message, its 25 raw bytes, or both
    Heard = Message | bytes | bytearray | memoryview | tuple[Message | None, bytes]

STATUSES = ("valid", "invalid", "absent", "unknown-key", "expired", "not-yet-valid")


@dataclass(frozen=True)
class AuthMessage:
    """One reassembled authentication message: its bytes, or why it is malformed. `fec`: it
    ended with a forward-error-correction page; `rebuilt`: the page index rebuilt from it."""

    auth_type: int
    timestamp: datetime | None
    data: bytes | None = None
    reason: str | None = None
    fec: bool = False
    rebuilt: int | None = None


@dataclass(frozen=True)
class AuthResult:
    """The DRIP verdict of one recording.

    status: valid / invalid / absent / unknown-key / expired / not-yet-valid (the last two: a
    signature that verifies, outside its VNB..VNA window; the reason then starts with
    "verified-but-expired" or "verified-but-not-yet-valid"); reason: one line (for all but
    a plain valid or absent); sam_types: the DRIP SAM types whose signatures verified ("link",
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
def _page0_body(p0: AuthPage0) -> bytes:
    """Bytes 2..24 of a page 0 (last page index, length, timestamp, data): what FEC covers."""
    ts = 0 if p0.timestamp is None else round((p0.timestamp - ODID_EPOCH).total_seconds())
    return struct.pack("<BBI", p0.last_page_index, p0.length, ts) + bytes(p0.data)


class _Open:
    """One message being collected: pages by index (each its bytes 2..24). `page0` is None for a
    message whose page 0 was lost (rebuilt from its FEC page on close, if it has one)."""

    __slots__ = ("auth_type", "page0", "pages", "conflict", "origin")

    def __init__(self, auth_type: int, page0: AuthPage0 | None = None, origin: str | None = None):
        self.auth_type = auth_type
        self.page0 = page0
        self.pages: dict[int, bytes] = {} if page0 is None else {0: _page0_body(page0)}
        self.conflict: str | None = None
        self.origin = origin  # why a page without a page 0 started this message

    def clash(self, page: int, data: bytes) -> str | None:
        """Why `page` cannot join this message (None if it can)."""
        last = self.page0.last_page_index if self.page0 is not None else None
        if last is not None and page > last:
            return f"auth type {self.auth_type}: page {page} past the last page index {last}"
        seen = self.pages.get(page)
        if seen is not None and seen != data:
            return f"auth type {self.auth_type}: page {page} seen twice with different bytes"
        return None


def reassemble(messages: Iterable[Message | None]) -> list[AuthMessage]:
    """Authentication pages (AuthPage0 / AuthPage, other messages ignored) -> messages.

    A page 0 opens (or, repeated identically, re-opens) a message of its auth type; pages
    1..15 join the message of their auth type that the latest page 0 opened, so messages
    sent one after another, repeated or interleaved with other auth types reassemble.

    A message may end with a forward-error-correction page (`has_fec_page`): its parity is
    checked when every page is there (a mismatch makes the message malformed), and any one
    missing page, page 0 included, is rebuilt from it. A page that does not fit the message
    it would join (past its last page index, or another page's bytes at its index) starts a
    message whose page 0 was lost when that message is already whole; otherwise it makes the
    message malformed. Missing pages beyond what FEC rebuilds, or a length impossible for the
    last page index, make a message malformed.
    """
    order: list[_Open] = []
    by_key: dict[tuple, _Open] = {}
    current: dict[int, _Open] = {}
    for m in messages:
        if isinstance(m, AuthPage0):
            key = (m.auth_type, m.last_page_index, m.length, m.timestamp, m.data)
            rec = by_key.get(key)
            if rec is None:
                rec = by_key[key] = _Open(m.auth_type, m)
                order.append(rec)
            current[m.auth_type] = rec
        elif isinstance(m, AuthPage):
            data = bytes(m.data)
            rec = current.get(m.auth_type)
            why = None if rec is None else rec.clash(m.page, data)
            if rec is None or (why and _close(rec).data is not None):
                # no page 0 yet, or the message is whole: a new message whose page 0 was lost
                rec = _Open(m.auth_type, origin=why or f"auth type {m.auth_type}: page {m.page} without a page 0")
                current[m.auth_type] = rec
                order.append(rec)
            elif why:
                rec.conflict = rec.conflict or why
                continue
            rec.pages[m.page] = data
    out: list[AuthMessage] = []
    seen: set[tuple] = set()
    for rec in order:
        msg = _close(rec)
        seen_key = (msg.auth_type, msg.timestamp, msg.data, msg.reason)
        if seen_key not in seen:  # a message rebuilt without its page 0 and also received whole
            seen.add(seen_key)
            out.append(msg)
    return out


def _close(rec: _Open) -> AuthMessage:
    """The message `rec` collected (without changing `rec`: more pages may still join it)."""
    t = rec.auth_type
    if rec.conflict:
        return AuthMessage(t, rec.page0.timestamp if rec.page0 else None, reason=rec.conflict)
    if rec.page0 is None:
        return _close_headless(rec)
    p0 = rec.page0
    ts, last, length = p0.timestamp, p0.last_page_index, p0.length
    fec = has_fec_page(length, last)
    if not fec and not length_fits(length, last):
        hi = PAGE0_DATA + PAGE_DATA * last
        return AuthMessage(t, ts, reason=(
            f"auth type {t}: length {length} impossible for last page index {last} "
            f"(max {hi}; {hi - PAGE_DATA} with an FEC page)"))
    pages = dict(rec.pages)
    missing = [k for k in range(last + 1) if k not in pages]
    rebuilt = None
    if fec and not missing:
        if xor_pages(pages[k] for k in range(last)) != pages[last]:
            return AuthMessage(t, ts, fec=True, reason=(
                f"auth type {t}: FEC parity error: page {last} is not the XOR of pages 0..{last - 1}"))
    elif fec and len(missing) == 1:
        if missing[0] != last:  # a lost FEC page needs no rebuilding
            rebuilt = missing[0]
            pages[rebuilt] = xor_pages(pages[k] for k in range(last + 1) if k != rebuilt)
    elif missing:
        return AuthMessage(t, ts, fec=fec, reason=(
            f"auth type {t}: page{'s' if len(missing) > 1 else ''} "
            f"{', '.join(map(str, missing))} of 0..{last} missing"
            + (" (the FEC page rebuilds one)" if fec else "")))
    n = last if fec else last + 1
    data = (pages[0][6:] + b"".join(pages[k] for k in range(1, n)))[:length]
    return AuthMessage(t, ts, data=data, fec=fec, rebuilt=rebuilt)


def _close_headless(rec: _Open) -> AuthMessage:
    """A message whose page 0 was lost: page 0 is the XOR of pages 1..L when page L is its FEC page."""
    t = rec.auth_type
    top = max(rec.pages)
    if sorted(rec.pages) == list(range(1, top + 1)):
        body = xor_pages(rec.pages.values())
        last, length, ts = struct.unpack_from("<BBI", body)
        if last == top and has_fec_page(length, last):
            data = (body[6:] + b"".join(rec.pages[k] for k in range(1, last)))[:length]
            return AuthMessage(t, from_drip_time(ts) if ts else None, data=data, fec=True, rebuilt=0)
    pages = ", ".join(map(str, sorted(rec.pages)))
    return AuthMessage(t, None, reason=(
        f"{rec.origin}; no page 0 for page{'s' if len(rec.pages) > 1 else ''} {pages}, "
        "and no FEC page rebuilds it"))


# ------------------------------------------------------------------ verification
def _split(item: Heard) -> tuple[Message | None, bytes | None]:
    """A decoded message, 25 raw bytes or a (message, raw) pair -> (message, raw)."""
    if isinstance(item, tuple) and len(item) == 2:
        return item[0], bytes(item[1])
    if isinstance(item, (bytes, bytearray, memoryview)):
        from remoteid.codec import decode

        raw = bytes(item)
        try:
            return decode(raw), raw
        except RemoteIdError:
            return None, raw
    return item, None


def _raw_of(msg: Message | None, raw: bytes | None) -> bytes | None:
    if raw is not None:
        return raw
    if msg is None:
        return None
    from remoteid.codec import encode

    try:
        return encode(msg)
    except RemoteIdError:
        return None


def verify(messages: Iterable[Heard], key_for: Callable[[bytes], bytes | None], dwell_time: datetime, *,
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


def _verify(items: list[tuple[Message | None, bytes | None]], decoded: list[Message | None],
            key_for: Callable[[bytes], bytes | None], dwell_time: datetime, trusted: Mapping[bytes, bytes],
            skew_s: float) -> AuthResult:
    """The verdict of the signed structures among `decoded`, link structures first (they may
    supply the UA key that the others are verified with)."""
    if dwell_time.tzinfo is None:
        return AuthResult("invalid", reason="dwell time must be timezone-aware")
    clock = _Clock(dwell_time.timestamp(), dwell_time.astimezone(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
                   skew_s)  # VNB / VNA are Unix times
    structures = _structures(decoded)
    if isinstance(structures, AuthResult):
        return structures
    subjects = _Subjects.of(items, decoded)
    tally = _Tally()
    for s in sorted(structures, key=lambda s: not isinstance(s, Link)):
        refused = (_link(s, trusted, clock, tally) if isinstance(s, Link)
                   else _signed(s, key_for, clock, subjects, tally))
        if refused is not None:
            return refused
    return tally.result(tally.signer_det or structures[0].det.hex())


def _sig_ok(key: bytes, sig: bytes, data: bytes) -> bool:
    """Whether `sig` is the Ed25519 signature of `data` under the raw public key `key`."""
    from cryptography.exceptions import InvalidSignature
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey

    try:
        Ed25519PublicKey.from_public_bytes(bytes(key)).verify(sig, data)
        return True
    except (InvalidSignature, ValueError):
        return False


@dataclass(frozen=True)
class _Clock:
    """The dwell's time (Unix seconds, and as text for reasons) and the clock skew allowed."""

    now: float
    at: str
    skew_s: float

    def outside(self, s: Signed | Link) -> tuple[str, str] | None:
        """(status, reason) of a verified signature outside its window, None inside it."""
        window = f"valid {valid_time_text(s.vnb)} to {valid_time_text(s.vna)}, checked at {self.at}"
        if self.now < s.vnb - self.skew_s:
            return "not-yet-valid", f"verified-but-not-yet-valid: DRIP {s.name} signature verifies ({window})"
        if self.now > s.vna + self.skew_s:
            return "expired", f"verified-but-expired: DRIP {s.name} signature verifies ({window})"
        return None


def _structures(decoded: list[Message | None]) -> list[Signed | Link] | AuthResult:
    """The DRIP signed structures (SAM) of the reassembled authentication messages, or the
    verdict where there are none (`absent`) or one is malformed (`invalid`)."""
    structures: list[Signed | Link] = []
    others = set()
    for am in reassemble(decoded):
        if am.reason or am.data is None:  # a message without its data says why
            return AuthResult("invalid", reason=am.reason or "an authentication message without data")
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
    return structures


@dataclass(frozen=True)
class _Subjects:
    """What a signature may cover: the decoded non-authentication messages, by their bytes and
    by their message hash (indices into the messages given)."""

    by_raw: dict[bytes, list[int]]
    by_hash: dict[bytes, list[int]]
    decoded: list[Message | None]

    @classmethod
    def of(cls, items: list[tuple[Message | None, bytes | None]], decoded: list[Message | None]) -> _Subjects:
        by_raw: dict[bytes, list[int]] = {}
        by_hash: dict[bytes, list[int]] = {}
        for i, (m, raw) in enumerate(items):
            if m is None or isinstance(m, (AuthPage0, AuthPage)):
                continue
            raw = _raw_of(m, raw)
            if raw is None:
                continue
            by_raw.setdefault(raw, []).append(i)
            by_hash.setdefault(message_hash(raw), []).append(i)
        return cls(by_raw, by_hash, decoded)

    def coverable(self, idx: list[int]) -> list[int]:
        """The indices among `idx` whose coverage counts (Basic ID and Location messages)."""
        return [i for i in idx if isinstance(self.decoded[i], (BasicId, Location))]


@dataclass
class _Tally:
    """What the structures verified so far showed: UA keys learned from links, the SAM types
    verified (and those verified outside their window), the messages covered, the keys missing."""

    learned: dict[bytes, bytes] = field(default_factory=dict)
    verified: list[str] = field(default_factory=list)
    covered: set[int] = field(default_factory=set)
    unknown: list[str] = field(default_factory=list)
    early: list[tuple[str, str]] = field(default_factory=list)  # (status, reason) outside their window
    late_types: list[str] = field(default_factory=list)
    signer_det: str | None = None

    def result(self, det_hex: str) -> AuthResult:
        """The verdict: outside a window (never `invalid`, never `valid`), valid, or unknown-key."""
        if self.early:
            status, reason = self.early[0]
            return AuthResult(status, reason=reason, sam_types=tuple(dict.fromkeys(self.verified + self.late_types)),
                              det=det_hex, details=tuple([r for _, r in self.early] + self.unknown))
        if self.verified:
            return AuthResult("valid", sam_types=tuple(dict.fromkeys(self.verified)),
                              covered=tuple(sorted(self.covered)), det=det_hex, details=tuple(self.unknown))
        return AuthResult("unknown-key", reason=self.unknown[0], det=det_hex, details=tuple(self.unknown))


def _link(s: Link, trusted: Mapping[bytes, bytes], clock: _Clock, tally: _Tally) -> AuthResult | None:
    """Verify a DRIP Link under its trusted HDA key; inside its window it supplies the UA key.
    Returns the `invalid` verdict where it fails, else None."""
    hda_key = trusted.get(s.hda_det)
    if hda_key is None:
        tally.unknown.append(f"DRIP link: HDA {s.hda_det.hex()} is not a trusted registry")
        return None
    if not _sig_ok(hda_key, s.signature, s.signed_bytes):
        return AuthResult("invalid", reason="DRIP link: HDA signature does not verify", det=s.ua_det.hex())
    if not det_matches_key(s.ua_det, s.ua_key):
        return AuthResult("invalid", reason="DRIP link: UA DET is not the DET of the UA key it carries",
                          det=s.ua_det.hex())
    if (why := clock.outside(s)) is not None:
        tally.early.append(why)
        tally.late_types.append("link")
        return None
    tally.learned[s.ua_det] = s.ua_key
    tally.verified.append("link")
    return None


def _signed(s: Signed, key_for: Callable[[bytes], bytes | None] | None, clock: _Clock, subjects: _Subjects,
            tally: _Tally) -> AuthResult | None:
    """Verify a Wrapper, Manifest or Frame under its DET's key (the registry's, else one a link
    supplied) and record the messages it covers. Returns the `invalid` verdict where it fails."""
    key = key_for(s.det) if key_for is not None else None
    key = key or tally.learned.get(s.det)
    if key is None:
        tally.unknown.append(f"DRIP {s.name}: no key for DET {s.det.hex()}")
        return None
    if not _sig_ok(key, s.signature, s.signed_bytes):
        return AuthResult("invalid", reason=f"DRIP {s.name}: signature does not verify", det=s.det.hex())
    if s.sam_type == SAM_MANIFEST and not s.manifest_current_ok():
        return AuthResult("invalid", det=s.det.hex(),
                          reason="DRIP manifest: current manifest hash does not match its evidence")
    if (why := clock.outside(s)) is not None:
        tally.early.append(why)
        tally.late_types.append(s.name)
        tally.signer_det = tally.signer_det or s.det.hex()
        return None
    carried = s.wrapped() if s.sam_type == SAM_WRAPPER else \
        s.frame_messages() if s.sam_type == SAM_FRAME else None
    if carried is not None:  # a Wrapper's messages, or a Frame of F3411 messages
        for k, w in enumerate(carried):
            idx = subjects.by_raw.get(w)
            if not idx:
                return AuthResult("invalid", det=s.det.hex(), reason=(
                    f"DRIP {s.name}: signed message {k + 1} (type 0x{w[0] >> 4:X}) "
                    "is not among the decoded messages"))
            tally.covered.update(subjects.coverable(idx))
    elif s.sam_type == SAM_MANIFEST:
        for h in s.manifest_hashes()[3]:
            tally.covered.update(subjects.coverable(subjects.by_hash.get(h, [])))
    tally.verified.append(s.name)
    tally.signer_det = tally.signer_det or s.det.hex()
    return None
