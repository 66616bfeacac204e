"""DRIP wire formats: DETs (RFC 9374), Authentication pages (F3411-22a), SAM structures (RFC 9575).

Pure formats, no signature checks (those are `drip_verify`). Imports only the standard
library (`cryptography` is imported inside the encode functions that sign).

Layouts as implemented (multi-byte integers little-endian as in F3411; timestamps are
seconds since 2019-01-01T00:00:00Z):

* Authentication page 0: header, auth type << 4 | 0, last page index, length (total auth
  data bytes), uint32 timestamp, 17 data bytes; pages 1..15: header, auth type << 4 | page,
  23 data bytes. A message with last page index L carries 17 + 23 L bytes, of which the
  first `length` are auth data (17 + 23 (L - 1) < length <= 17 + 23 L).
* Forward error correction (RFC 9575 Section 4.2.1, as its examples send it): a message may
  end with one FEC page. Its last page index counts the FEC page, its length does not (so
  length fits L - 1, not L), and the FEC page's bytes 2..24 are the XOR of bytes 2..24 of
  every page before it (page 0 from its last page index byte on: last page index, length,
  timestamp and data). One missing page is the XOR of all the others.
* SAM auth data (auth type 0x5): SAM type (1) then the SAM data. DRIP SAM types:
  0x01 Link, 0x02 Wrapper, 0x03 Manifest, 0x04 Frame.
* VNB / VNA (valid not before / after) are uint32 Unix times (seconds since 1970-01-01 UTC,
  as the RFC 9575 examples carry them: VNB 2023-12-15T23:14:40Z), unlike the page-0 timestamp
  (seconds since 2019-01-01, F3411).
* UA-signed structure (Wrapper, Manifest, Frame): VNB (4) | VNA (4) | evidence (0..112) |
  UA DET (16) | Ed25519 signature (64) over VNB | VNA | evidence | DET.
  - Wrapper evidence: 0..4 whole 25-byte F3411 messages.
  - Manifest evidence: previous manifest hash (8) | current manifest hash (8) | DRIP Link
    hash (8) | 0..11 message hashes (8 each); every hash is cSHAKE128(x, 64 bits, N = "",
    S = "Remote ID Auth Hash"); the current manifest hash is the hash of the evidence with
    its own 8 bytes zeroed.
  - Frame evidence: frame type (1) | frame (0..111 bytes).
* Link (a Broadcast Endorsement of the UA by its HDA): VNB (4) | VNA (4) | UA DET (16) |
  UA HI (32, Ed25519 public key) | HDA DET (16) | HDA signature (64) over everything
  before it (without the SAM type): 137 bytes with the SAM type.
* DET (RFC 9374): prefix 2001:30::/28 | RAA (14 bits) | HDA (14 bits) | suite ID (8 bits,
  5 = EdDSA/cSHAKE128) | 64-bit hash, the hash being cSHAKE128(prefix | HID | suite |
  HI, 64 bits, N = "", S = ORCHID Context ID 0x00B5A69C795DF5D5F0087F56843F2C40) with HI
  the raw 32-byte Ed25519 public key. This reproduces the DET of the RFC 9575 examples
  (host identity b5fef530...041813 -> 2001:3f:fe00:105:a29b:3ff4:2226:c04e); the
  HOST_ID form with a curve id and padding before the key (used before) does not.
"""

from __future__ import annotations

import hashlib
import ipaddress
import struct
from dataclasses import dataclass
from datetime import datetime, timezone
from collections.abc import Iterable
from typing import TYPE_CHECKING, NamedTuple, cast

from remoteid.errors import RemoteIdError
from remoteid.messages import ODID_EPOCH

if TYPE_CHECKING:
    from _hashlib import HASHXOF

    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

    from remoteid.messages import Message

    #: a signing key: the object, or its 32 raw bytes
    SigningKey = Ed25519PrivateKey | bytes | bytearray
    #: a message to sign: the model, or its 25 wire bytes
    Signable = Message | bytes | bytearray | memoryview

PAGE_SIZE = 25
PAGE0_DATA = 17
PAGE_DATA = 23
MAX_PAGES = 16
MAX_AUTH_LENGTH = 255  # the page-0 length field is one byte
AUTH_TYPE_SAM = 0x5

SAM_LINK, SAM_WRAPPER, SAM_MANIFEST, SAM_FRAME = 0x01, 0x02, 0x03, 0x04
SAM_NAMES = {SAM_LINK: "link", SAM_WRAPPER: "wrapper", SAM_MANIFEST: "manifest", SAM_FRAME: "frame"}

#: Our Frame type (RFC 9575 leaves 0xC0-0xFF for experimental use): the frame is whole 25-byte
#: F3411 messages, checked against the messages decoded like a Wrapper's.
FRAME_F3411_MESSAGES = 0xC0
DET_SIZE = 16
SIG_SIZE = 64
KEY_SIZE = 32
HASH_SIZE = 8
MAX_EVIDENCE = 112
MAX_WRAPPED = 4
MAX_MESSAGE_HASHES = 11
LINK_SIZE = 1 + 4 + 4 + DET_SIZE + KEY_SIZE + DET_SIZE + SIG_SIZE  # 137

DET_PREFIX = 0x2001003  # the top 28 bits of 2001:30::/28
SUITE_EDDSA_CSHAKE128 = 5
DET_CONTEXT_ID = bytes.fromhex("00B5A69C795DF5D5F0087F56843F2C40")
HASH_CUSTOMIZATION = b"Remote ID Auth Hash"


class DripError(RemoteIdError):
    """Malformed DRIP authentication data (one-line reason)."""


# ------------------------------------------------------------------ cSHAKE128
def _left_encode(x: int) -> bytes:
    n = max(1, (x.bit_length() + 7) // 8)
    return bytes([n]) + x.to_bytes(n, "big")


_CSHAKE_PREFIX: dict[bytes, bytes] = {}


def cshake128(data: bytes, out_len: int, customization: bytes, name: bytes = b"") -> bytes:
    """cSHAKE128(X, 8 out_len bits, N, S) of NIST SP 800-185 on OpenSSL's Keccak.

    The sponge is OpenSSL's KECCAK-KMAC-128 digest (Keccak[256] with the 0b00 domain bits
    that cSHAKE uses); hashlib's shake_128 equals cSHAKE only when N and S are both empty,
    which RFC 9374 and RFC 9575 do not use. Checked against the NIST cSHAKE samples in the
    tests. Raises DripError when this OpenSSL lacks the digest.
    """
    if not name and not customization:
        return hashlib.shake_128(data).digest(out_len)
    key = name + b"\0" + customization
    prefix = _CSHAKE_PREFIX.get(key)
    if prefix is None:
        enc = (_left_encode(len(name) * 8) + name + _left_encode(len(customization) * 8)
               + customization)
        z = _left_encode(168) + enc
        prefix = _CSHAKE_PREFIX[key] = z + bytes(-len(z) % 168)
    try:
        h = cast("HASHXOF", hashlib.new("KECCAK-KMAC-128"))  # variable length, as SHAKE
    except ValueError:
        raise DripError("cSHAKE128 needs OpenSSL >= 3 (digest KECCAK-KMAC-128)") from None
    h.update(prefix + data)
    return h.digest(out_len)


def message_hash(data: bytes) -> bytes:
    """The 8-byte DRIP Manifest hash of `data` (a 25-byte message, a pack, a Link's auth data)."""
    return cshake128(bytes(data), HASH_SIZE, HASH_CUSTOMIZATION)


# ------------------------------------------------------------------ DETs
class DetFields(NamedTuple):
    raa: int
    hda: int
    suite_id: int
    hash: bytes


def _hid_bytes(raa: int, hda: int, suite: int) -> bytes:
    return ((DET_PREFIX << 36) | (raa << 22) | (hda << 8) | suite).to_bytes(8, "big")


def det_from_public_key(public_key_raw: bytes, raa: int, hda: int) -> bytes:
    """16-byte DET of an Ed25519 public key under RAA/HDA (RFC 9374, suite 5)."""
    public_key_raw = bytes(public_key_raw)
    if len(public_key_raw) != KEY_SIZE:
        raise DripError(f"Ed25519 public key: {len(public_key_raw)} bytes, expected {KEY_SIZE}")
    for what, v in (("RAA", raa), ("HDA", hda)):
        if not 0 <= v <= 0x3FFF:
            raise DripError(f"{what} {v} out of range 0..16383")
    head = _hid_bytes(raa, hda, SUITE_EDDSA_CSHAKE128)
    return head + cshake128(head + public_key_raw, 8, DET_CONTEXT_ID)  # ORCHID input: head | raw key


def det_fields(det: bytes) -> DetFields:
    det = parse_det(det)
    top = int.from_bytes(det[:8], "big")
    return DetFields((top >> 22) & 0x3FFF, (top >> 8) & 0x3FFF, top & 0xFF, det[8:])


def det_matches_key(det: bytes, public_key_raw: bytes) -> bool:
    """Whether `det` is the DET of `public_key_raw` (its own RAA/HDA, suite 5)."""
    f = det_fields(det)
    return f.suite_id == SUITE_EDDSA_CSHAKE128 and det_from_public_key(public_key_raw, f.raa, f.hda) == det


def det_to_text(det: bytes) -> str:
    """IPv6 text form (RFC 5952, e.g. 2001:30:280:1405:...)."""
    return str(ipaddress.IPv6Address(parse_det(det)))


def parse_det(value: bytes | bytearray | str) -> bytes:
    """16 DET bytes from bytes, IPv6 text or 32 hex digits; checks the 2001:30::/28 prefix."""
    if isinstance(value, str):
        text = value.strip()
        try:
            raw = ipaddress.IPv6Address(text).packed if ":" in text else bytes.fromhex(text)
        except ValueError:
            raise DripError(f"not a DET: {value[:60]!r}") from None
    else:
        raw = bytes(value)
    if len(raw) != DET_SIZE:
        raise DripError(f"DET: {len(raw)} bytes, expected {DET_SIZE}")
    if int.from_bytes(raw[:4], "big") >> 4 != DET_PREFIX:
        raise DripError(f"DET {raw.hex()} is outside 2001:30::/28")
    return raw


# ------------------------------------------------------------------ times
def to_drip_time(value: datetime | int) -> int:
    """Seconds since 2019-01-01 UTC (the F3411 Authentication page-0 timestamp)."""
    if isinstance(value, datetime):
        if value.tzinfo is None:
            raise DripError("timestamps must be timezone-aware")
        value = int((value - ODID_EPOCH).total_seconds())
    if not 0 <= int(value) <= 0xFFFFFFFF:
        raise DripError(f"timestamp {value} outside the uint32 range after 2019-01-01")
    return int(value)


def from_drip_time(value: int) -> datetime:
    return datetime.fromtimestamp(ODID_EPOCH.timestamp() + value, tz=timezone.utc)


def to_valid_time(value: datetime | int) -> int:
    """A VNB / VNA field: uint32 Unix time (seconds since 1970-01-01 UTC), as RFC 9575's examples."""
    if isinstance(value, datetime):
        if value.tzinfo is None:
            raise DripError("timestamps must be timezone-aware")
        value = int(value.timestamp())
    if not 0 <= int(value) <= 0xFFFFFFFF:
        raise DripError(f"valid-not-before/after {value} outside the uint32 range of Unix times")
    return int(value)


def from_valid_time(value: int) -> datetime:
    """A VNB / VNA field as a UTC datetime."""
    return datetime.fromtimestamp(value, tz=timezone.utc)


def valid_time_text(value: int) -> str:
    """A VNB / VNA field as ISO 8601 UTC text (2023-12-15T23:14:40Z)."""
    return from_valid_time(value).strftime("%Y-%m-%dT%H:%M:%SZ")


# ------------------------------------------------------------------ pages
def paginate(auth_data: bytes, timestamp: datetime | int, *, auth_type: int = AUTH_TYPE_SAM,
             protocol_version: int = 2, fec: bool = False) -> list[bytes]:
    """Authentication pages (25 bytes each, page 0 first) carrying `auth_data`; with `fec`, one
    more page at the end: the forward-error-correction page (XOR parity, see the module doc)."""
    auth_data = bytes(auth_data)
    n = len(auth_data)
    if not 0 < n <= MAX_AUTH_LENGTH:
        raise DripError(f"auth data of {n} bytes: 1..{MAX_AUTH_LENGTH} fit the length field")
    last = 0 if n <= PAGE0_DATA else -(-(n - PAGE0_DATA) // PAGE_DATA)
    padded = auth_data + bytes(PAGE0_DATA + PAGE_DATA * last - n)
    head = 0x20 | protocol_version
    pages = [struct.pack("<BBBBI17s", head, auth_type << 4, last + bool(fec), n, to_drip_time(timestamp),
                         padded[:PAGE0_DATA])]
    for k in range(1, last + 1):
        off = PAGE0_DATA + PAGE_DATA * (k - 1)
        pages.append(bytes([head, auth_type << 4 | k]) + padded[off:off + PAGE_DATA])
    if fec:  # last + 1 <= 12 for 255 bytes: always a page index 1..15
        pages.append(bytes([head, auth_type << 4 | (last + 1)]) + xor_pages(p[2:] for p in pages))
    return pages


def xor_pages(bodies: Iterable[bytes]) -> bytes:
    """Byte-wise XOR of 23-byte page bodies (bytes 2..24 of each page): the FEC parity."""
    acc = 0
    for b in bodies:
        if len(b) != PAGE_DATA:
            raise DripError(f"a page body is {PAGE_DATA} bytes, got {len(b)}")
        acc ^= int.from_bytes(b, "big")
    return acc.to_bytes(PAGE_DATA, "big")


def length_fits(length: int, last_page_index: int) -> bool:
    """Whether a page-0 length is possible for its last page index (F3411-22a)."""
    top = PAGE0_DATA + PAGE_DATA * last_page_index
    low = PAGE0_DATA + PAGE_DATA * (last_page_index - 1) if last_page_index else 0
    return low < length <= top


def has_fec_page(length: int, last_page_index: int) -> bool:
    """Whether a page-0 length and last page index say the last page is an FEC page: the length
    needs exactly one page fewer than the index counts (never ambiguous with `length_fits`)."""
    return last_page_index >= 1 and length_fits(length, last_page_index - 1)


# ------------------------------------------------------------------ SAM structures
@dataclass(frozen=True)
class Signed:
    """A UA-signed SAM structure (Wrapper, Manifest, Frame)."""

    sam_type: int
    vnb: int
    vna: int
    evidence: bytes
    det: bytes
    signature: bytes

    @property
    def signed_bytes(self) -> bytes:
        return struct.pack("<II", self.vnb, self.vna) + self.evidence + self.det

    @property
    def name(self) -> str:
        return SAM_NAMES[self.sam_type]

    def wrapped(self) -> list[bytes]:
        return [self.evidence[i:i + 25] for i in range(0, len(self.evidence), 25)]

    def frame_messages(self) -> list[bytes] | None:
        """The F3411 messages a Frame of type FRAME_F3411_MESSAGES carries (None for others)."""
        frame_type, frame = self.evidence[:1], self.evidence[1:]
        if frame_type != bytes([FRAME_F3411_MESSAGES]) or not frame or len(frame) % 25:
            return None
        return [frame[i:i + 25] for i in range(0, len(frame), 25)]

    def manifest_hashes(self) -> tuple[bytes, bytes, bytes, list[bytes]]:
        """(previous, current, link, message hashes) of a Manifest."""
        e = self.evidence
        return e[0:8], e[8:16], e[16:24], [e[i:i + 8] for i in range(24, len(e), 8)]

    def manifest_current_ok(self) -> bool:
        e = self.evidence
        return message_hash(e[:8] + bytes(8) + e[16:]) == e[8:16]


@dataclass(frozen=True)
class Link:
    """A DRIP Link: the HDA's Broadcast Endorsement of the UA's DET and key."""

    vnb: int
    vna: int
    ua_det: bytes
    ua_key: bytes
    hda_det: bytes
    signature: bytes
    sam_type: int = SAM_LINK
    name: str = "link"

    @property
    def signed_bytes(self) -> bytes:
        return struct.pack("<II", self.vnb, self.vna) + self.ua_det + self.ua_key + self.hda_det

    @property
    def det(self) -> bytes:
        return self.ua_det


def parse_sam(auth_data: bytes) -> Signed | Link:
    """One reassembled auth type 0x5 message -> its DRIP structure; DripError if malformed."""
    d = bytes(auth_data)
    if not d:
        raise DripError("SAM auth data is empty")
    sam = d[0]
    if sam not in SAM_NAMES:
        raise DripError(f"SAM type 0x{sam:02X} is not a DRIP type (0x01..0x04)")
    name = SAM_NAMES[sam]
    if sam == SAM_LINK:
        if len(d) != LINK_SIZE:
            raise DripError(f"DRIP link: {len(d)} bytes, expected {LINK_SIZE}")
        vnb, vna = struct.unpack_from("<II", d, 1)
        link = Link(vnb, vna, d[9:25], d[25:57], d[57:73], d[73:137])
        _check_window(name, vnb, vna)
        return link
    body = len(d) - 1 - 8 - DET_SIZE - SIG_SIZE
    if body < 0:
        raise DripError(f"DRIP {name}: {len(d)} bytes, too short for VNB, VNA, DET and signature")
    if body > MAX_EVIDENCE:
        raise DripError(f"DRIP {name}: {body} evidence bytes, at most {MAX_EVIDENCE}")
    vnb, vna = struct.unpack_from("<II", d, 1)
    _check_window(name, vnb, vna)
    ev = d[9:9 + body]
    if sam == SAM_WRAPPER and body % 25:
        raise DripError(f"DRIP wrapper: {body} evidence bytes, not whole 25-byte messages")
    if sam == SAM_MANIFEST and (body < 24 or body % 8):
        raise DripError(f"DRIP manifest: {body} evidence bytes, not 3 + n 8-byte hashes")
    if sam == SAM_FRAME and body < 1:
        raise DripError("DRIP frame: no frame type")
    det = d[9 + body:25 + body]
    return Signed(sam, vnb, vna, ev, det, d[25 + body:])


def _check_window(name: str, vnb: int, vna: int) -> None:
    if vna < vnb:
        raise DripError(f"DRIP {name}: valid-not-after {vna} before valid-not-before {vnb}")


# ------------------------------------------------------------------ encode (signing)
def _signer(private_key: SigningKey) -> Ed25519PrivateKey:
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

    if isinstance(private_key, (bytes, bytearray)):
        return Ed25519PrivateKey.from_private_bytes(bytes(private_key))
    return private_key


def _raw(message: Signable) -> bytes:
    if isinstance(message, (bytes, bytearray, memoryview)):
        raw = bytes(message)
    else:
        from remoteid.codec import encode

        raw = encode(message)
    if len(raw) != 25:
        raise DripError(f"a signed message must be one 25-byte F3411 message, got {len(raw)} bytes")
    return raw


def _encode_signed(sam: int, evidence: bytes, det: bytes, private_key: SigningKey, vnb: datetime | int,
                   vna: datetime | int) -> bytes:
    det = parse_det(det)
    lo, hi = to_valid_time(vnb), to_valid_time(vna)
    _check_window(SAM_NAMES[sam], lo, hi)
    if len(evidence) > MAX_EVIDENCE:
        raise DripError(f"DRIP {SAM_NAMES[sam]}: {len(evidence)} evidence bytes, at most {MAX_EVIDENCE}")
    signed = struct.pack("<II", lo, hi) + evidence + det
    return bytes([sam]) + signed + _signer(private_key).sign(signed)


def encode_wrapper(messages: Iterable[Signable], det: bytes, private_key: SigningKey, vnb: datetime | int,
                   vna: datetime | int) -> bytes:
    """Auth data of a DRIP Wrapper over 0..4 F3411 messages (models or 25-byte bytes)."""
    raws = [_raw(m) for m in messages]
    if len(raws) > MAX_WRAPPED:
        raise DripError(f"a DRIP wrapper holds at most {MAX_WRAPPED} messages, got {len(raws)}")
    return _encode_signed(SAM_WRAPPER, b"".join(raws), det, private_key, vnb, vna)


def encode_manifest(messages: Iterable[Signable], det: bytes, private_key: SigningKey, vnb: datetime | int,
                    vna: datetime | int, *,
                    previous_hash: bytes = bytes(8), link_hash: bytes = bytes(8)) -> bytes:
    """Auth data of a DRIP Manifest over the hashes of 0..11 F3411 messages."""
    hashes = [message_hash(_raw(m)) for m in messages]
    if len(hashes) > MAX_MESSAGE_HASHES:
        raise DripError(f"a DRIP manifest holds at most {MAX_MESSAGE_HASHES} hashes, got {len(hashes)}")
    if len(previous_hash) != 8 or len(link_hash) != 8:
        raise DripError("manifest previous and link hashes are 8 bytes")
    tail = bytes(link_hash) + b"".join(hashes)
    current = message_hash(bytes(previous_hash) + bytes(8) + tail)
    return _encode_signed(SAM_MANIFEST, bytes(previous_hash) + current + tail, det, private_key, vnb, vna)


def encode_frame(frame_type: int, frame: bytes, det: bytes, private_key: SigningKey, vnb: datetime | int,
                 vna: datetime | int) -> bytes:
    """Auth data of a DRIP Frame: a signed frame of `frame_type` (up to 111 bytes)."""
    if not 0 <= frame_type <= 255:
        raise DripError(f"frame type {frame_type} out of range 0..255")
    return _encode_signed(SAM_FRAME, bytes([frame_type]) + bytes(frame), det, private_key, vnb, vna)


def encode_link(ua_det: bytes, ua_public_key: bytes, hda_det: bytes, hda_private_key: SigningKey,
                vnb: datetime | int, vna: datetime | int) -> bytes:
    """Auth data of a DRIP Link: the HDA's endorsement of the UA's DET and Ed25519 key."""
    ua_det, hda_det = parse_det(ua_det), parse_det(hda_det)
    if len(ua_public_key) != KEY_SIZE:
        raise DripError(f"UA public key: {len(ua_public_key)} bytes, expected {KEY_SIZE}")
    lo, hi = to_valid_time(vnb), to_valid_time(vna)
    _check_window("link", lo, hi)
    signed = struct.pack("<II", lo, hi) + ua_det + bytes(ua_public_key) + hda_det
    return bytes([SAM_LINK]) + signed + _signer(hda_private_key).sign(signed)
