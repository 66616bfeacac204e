"""Find Open Drone ID messages in pcap / pcapng captures (our own `struct` reader).

Transports: Wi-Fi beacon vendor IE (OUI FA:0B:BC, type 0x0D), Wi-Fi NAN
service discovery frames (service ID = first 6 bytes of SHA-256 of
"org.opendroneid.remoteid"), Bluetooth LE advertising service data (UUID
0xFFFA, app code 0x0D): legacy 25-byte messages and BT5 extended advertising
message packs. Link types: 105 (802.11), 127 (radiotap), 251 (BLE LL),
256 (BLE LL with pseudo-header), 272 (Nordic BLE sniffer).
"""

from __future__ import annotations

import hashlib
import os
import stat
import struct
from collections.abc import Iterator
from datetime import datetime, timedelta, timezone
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from core.checked import Checked
from remoteid.codec import MESSAGE_SIZE, decode
from remoteid.errors import CaptureError, RemoteIdError
from remoteid.messages import Message

Transport = Literal["wifi_beacon", "wifi_nan", "bt_legacy", "bt_extended"]

LINKTYPE_IEEE802_11 = 105
LINKTYPE_RADIOTAP = 127
LINKTYPE_BLE_LL = 251
LINKTYPE_BLE_LL_PHDR = 256
LINKTYPE_NORDIC_BLE = 272

ODID_OUI_TYPE = b"\xfa\x0b\xbc\x0d"
NAN_OUI_TYPE = b"\x50\x6f\x9a\x13"
NAN_SERVICE_ID = hashlib.sha256(b"org.opendroneid.remoteid").digest()[:6]
BLE_ADV_ACCESS_ADDRESS = 0x8E89BED6
ODID_BT_UUID = b"\xfa\xff"  # 0xFFFA little-endian
ODID_APP_CODE = 0x0D

_EPOCH = datetime(1970, 1, 1, tzinfo=timezone.utc)


@dataclass(frozen=True, kw_only=True)
class CapturedMessage(Checked):
    """One Open Drone ID payload (a message or a message pack) found in a capture."""

    frame: int  # 1-based packet number in the file
    captured_at: datetime | None  # None only for pcapng simple packet blocks
    transport: Transport
    counter: int  # the transport's message counter byte
    message: Message
    #: the transmitter's address (Wi-Fi source MAC, BLE AdvA) as aa:bb:..; None when the frame has none
    sender: str | None = None
    #: the payload's wire bytes (one 25-byte message or a whole pack); not in the JSON
    raw: bytes = field(default=b"", repr=False)

    def to_dict(self, *, json: bool = False, exclude: tuple[str, ...] = ("raw",)) -> dict[str, Any]:
        """The fields without `raw` (by default), the message as its dict."""
        return super().to_dict(json=json, exclude=exclude)


# ------------------------------------------------------------------ containers
def _ts(ticks: int, per_second: int, n: int) -> datetime:
    """Capture time of packet n from ticks since 1970 at per_second ticks per second.

    A time past year 9999 (a corrupt or hostile 64-bit pcapng timestamp; datetime cannot
    hold it) raises CaptureError naming the packet, like any other corrupt record: a
    capture whose clock cannot be trusted is refused, not decoded with a guessed time.
    """
    sec, frac = divmod(ticks, per_second)
    try:
        return _EPOCH + timedelta(seconds=sec, microseconds=frac * 1_000_000 // per_second)
    except OverflowError:
        raise CaptureError(f"packet {n}: timestamp out of range ({ticks} ticks at {per_second}/s)") from None


def _pcap_packets(data: bytes) -> Iterator[tuple[datetime | None, int, bytes]]:
    magic = data[:4]
    endian = {b"\xd4\xc3\xb2\xa1": "<", b"\xa1\xb2\xc3\xd4": ">",
              b"\x4d\x3c\xb2\xa1": "<", b"\xa1\xb2\x3c\x4d": ">"}[magic]
    per_second = 1_000_000_000 if magic in (b"\x4d\x3c\xb2\xa1", b"\xa1\xb2\x3c\x4d") else 1_000_000
    if len(data) < 24:
        raise CaptureError("truncated pcap header")
    linktype = struct.unpack_from(endian + "I", data, 20)[0] & 0xFFFF
    rec = struct.Struct(endian + "IIII")
    off, n = 24, 0
    while off < len(data):
        n += 1
        if off + 16 > len(data):
            raise CaptureError(f"packet {n}: truncated record header")
        sec, frac, incl, _ = rec.unpack_from(data, off)
        if frac >= per_second or off + 16 + incl > len(data):
            raise CaptureError(f"packet {n}: corrupt record (length {incl})")
        yield _ts(sec * per_second + frac, per_second, n), linktype, data[off + 16:off + 16 + incl]
        off += 16 + incl


def _pcapng_packets(data: bytes) -> Iterator[tuple[datetime | None, int, bytes]]:
    endian = "<"
    ifaces: list[tuple[int, int]] = []  # (linktype, ticks per second)
    off, n = 0, 0
    while off < len(data):
        if off + 12 > len(data):
            raise CaptureError(f"pcapng: truncated block at byte {off}")
        btype = struct.unpack_from(endian + "I", data, off)[0]
        if btype == 0x0A0D0D0A:  # section header: byte order may change
            bom = data[off + 8:off + 12]
            if bom not in (b"\x4d\x3c\x2b\x1a", b"\x1a\x2b\x3c\x4d"):
                raise CaptureError("pcapng: bad byte-order magic")
            endian = "<" if bom == b"\x4d\x3c\x2b\x1a" else ">"
            ifaces = []
        blen = struct.unpack_from(endian + "I", data, off + 4)[0]
        if blen < 12 or blen % 4 or off + blen > len(data):
            raise CaptureError(f"pcapng: corrupt block length {blen} at byte {off}")
        body = data[off + 8:off + blen - 4]
        if btype == 1:
            if len(body) < 8:
                raise CaptureError("pcapng: truncated interface block")
            ifaces.append((struct.unpack_from(endian + "H", body)[0], _tsresol(body[8:], endian)))
        elif btype in (6, 3, 2):
            n += 1
            yield _pcapng_packet(btype, body, endian, ifaces, n)
        off += blen


def _tsresol(options: bytes, endian: str) -> int:
    off = 0
    while off + 4 <= len(options):
        code, length = struct.unpack_from(endian + "HH", options, off)
        if code == 0:
            break
        if code == 9 and length >= 1 and off + 4 < len(options):
            v = options[off + 4]
            return 2 ** (v & 0x7F) if v & 0x80 else 10 ** v
        off += 4 + (length + 3) // 4 * 4
    return 1_000_000


def _pcapng_packet(btype: int, body: bytes, endian: str, ifaces: list[tuple[int, int]],
                   n: int) -> tuple[datetime | None, int, bytes]:
    try:
        if btype == 3:  # simple packet block: interface 0, no timestamp
            orig = struct.unpack_from(endian + "I", body)[0]
            return None, ifaces[0][0], body[4:4 + orig]
        if btype == 6:
            iface, hi, lo, cap, _ = struct.unpack_from(endian + "IIIII", body)
            pkt = body[20:20 + cap]
        else:  # obsolete packet block
            iface, _, hi, lo, cap, _ = struct.unpack_from(endian + "HHIIII", body)
            pkt = body[20:20 + cap]
        linktype, per_second = ifaces[iface]
    except (struct.error, IndexError):
        raise CaptureError(f"packet {n}: corrupt packet block") from None
    if len(pkt) != cap:
        raise CaptureError(f"packet {n}: captured length {cap} exceeds its block")
    return _ts((hi << 32) | lo, per_second, n), linktype, pkt


#: the first four bytes of a pcapng file (its section header block), and of a pcap file (either
#: byte order, microsecond or nanosecond times)
PCAPNG_MAGIC = b"\x0a\x0d\x0d\x0a"
PCAP_MAGICS = (b"\xd4\xc3\xb2\xa1", b"\xa1\xb2\xc3\xd4", b"\x4d\x3c\xb2\xa1", b"\xa1\xb2\x3c\x4d")


def capture_format(head: bytes) -> str | None:
    """'pcapng' or 'pcap' by a file's magic number (its first four bytes), else None."""
    return "pcapng" if head[:4] == PCAPNG_MAGIC else "pcap" if head[:4] in PCAP_MAGICS else None


def packets(data: bytes) -> Iterator[tuple[datetime | None, int, bytes]]:
    """(capture time, link type, packet bytes) for every packet of a pcap/pcapng file."""
    kind = capture_format(data)
    if kind == "pcapng":
        return _pcapng_packets(data)
    if kind == "pcap":
        return _pcap_packets(data)
    raise CaptureError("not a pcap or pcapng file (unknown magic number)")


# ------------------------------------------------------------------ Wi-Fi
def _radiotap(pkt: bytes) -> bytes | None:
    """802.11 frame inside a radiotap header; None for frames with a bad FCS."""
    if len(pkt) < 8:
        return None
    rlen = struct.unpack_from("<H", pkt, 2)[0]
    present = struct.unpack_from("<I", pkt, 4)[0]
    off = 8
    p = present
    while p & 0x80000000 and off + 4 <= len(pkt):
        p = struct.unpack_from("<I", pkt, off)[0]
        off += 4
    flags = 0
    if present & 0x1:
        off = (off + 7) // 8 * 8 + 8
    if present & 0x2 and off < rlen:
        flags = pkt[off]
    frame = pkt[rlen:]
    if flags & 0x40:  # bad FCS
        return None
    return frame[:-4] if flags & 0x10 else frame


def _ies(body: bytes) -> Iterator[tuple[int, bytes]]:
    off = 0
    while off + 2 <= len(body):
        eid, length = body[off], body[off + 1]
        if off + 2 + length > len(body):
            return
        yield eid, body[off + 2:off + 2 + length]
        off += 2 + length


def _mac(b: bytes) -> str:
    return ":".join(f"{x:02x}" for x in b)


def _wifi(frame: bytes) -> Iterator[tuple[Transport, bytes, str | None]]:
    if len(frame) < 24 or (frame[0] >> 2) & 0x3 != 0:
        return
    subtype = frame[0] >> 4
    body = frame[24:]
    sender = _mac(frame[10:16])  # address 2: the transmitter of a management frame
    if subtype in (5, 8):  # probe response, beacon
        for eid, ie in _ies(body[12:]):
            if eid == 221 and ie[:4] == ODID_OUI_TYPE and len(ie) > 5:
                yield "wifi_beacon", ie[4:], sender
    elif subtype in (13, 14) and body[:2] == b"\x04\x09" and body[2:6] == NAN_OUI_TYPE:
        for transport, info in _nan_attributes(body[6:]):
            yield transport, info, sender


def _nan_attributes(attrs: bytes) -> Iterator[tuple[Transport, bytes]]:
    off = 0
    while off + 3 <= len(attrs):
        aid, alen = attrs[off], struct.unpack_from("<H", attrs, off + 1)[0]
        attr = attrs[off + 3:off + 3 + alen]
        off += 3 + alen
        if aid != 0x03 or attr[:6] != NAN_SERVICE_ID or len(attr) < 9:
            continue
        control, pos = attr[8], 9
        if control & 0x40:  # binding bitmap
            pos += 2
        for bit in (0x04, 0x08):  # matching filter, service response filter
            if control & bit and pos < len(attr):
                pos += 1 + attr[pos]
        if control & 0x10 and pos < len(attr):
            info = attr[pos + 1:pos + 1 + attr[pos]]
            if len(info) > 1:
                yield "wifi_nan", info


# ------------------------------------------------------------------ Bluetooth
def _ble_ll(pkt: bytes, coded: bool = False) -> Iterator[tuple[Transport, bytes, str | None]]:
    if len(pkt) < 6 or struct.unpack_from("<I", pkt)[0] != BLE_ADV_ACCESS_ADDRESS:
        return
    off = 5 if coded else 4  # coded PHY: coding indicator byte
    if off + 2 > len(pkt):
        return
    pdu_type, length = pkt[off] & 0xF, pkt[off + 1]
    payload = pkt[off + 2:off + 2 + length]
    sender = None
    transport: Transport
    if pdu_type in (0, 2, 4, 6):  # ADV_IND, ADV_NONCONN_IND, SCAN_RSP, ADV_SCAN_IND
        adv, transport = payload[6:], "bt_legacy"
        sender = _mac(payload[5::-1]) if len(payload) >= 6 else None  # AdvA, little-endian on air
    elif pdu_type == 7 and payload:  # extended advertising (AUX_ADV_IND, AUX_CHAIN_IND)
        adv, transport = payload[1 + (payload[0] & 0x3F):], "bt_extended"
        if payload[0] & 0x3F >= 7 and payload[1] & 0x01:  # extended header with AdvA
            sender = _mac(payload[7:1:-1])
    else:
        return
    off = 0
    while off + 2 <= len(adv):
        length = adv[off]
        if length == 0 or off + 1 + length > len(adv):
            return
        ad_type, ad = adv[off + 1], adv[off + 2:off + 1 + length]
        off += 1 + length
        if ad_type == 0x16 and ad[:2] == ODID_BT_UUID and len(ad) > 4 and ad[2] == ODID_APP_CODE:
            yield transport, ad[3:], sender


def _nordic(pkt: bytes) -> Iterator[tuple[Transport, bytes, str | None]]:
    """Nordic nRF Sniffer (link type 272): board id, header, then the BLE LL packet.

    Packets whose CRC failed are skipped.
    """
    if len(pkt) < 8 or pkt[6] != 0x02:  # packet id 2: a received BLE packet
        return
    hdr_len = pkt[7]
    flags = pkt[8]
    if not flags & 0x01:  # CRC failed: the bytes are not what was sent
        return
    coded = pkt[3] >= 3 and (flags >> 4) & 0x7 == 2
    yield from _ble_ll(pkt[7 + hdr_len:], coded)


def _payloads(linktype: int, pkt: bytes) -> Iterator[tuple[Transport, bytes, str | None]]:
    if linktype == LINKTYPE_RADIOTAP:
        frame = _radiotap(pkt)
        if frame is not None:
            yield from _wifi(frame)
    elif linktype == LINKTYPE_IEEE802_11:
        yield from _wifi(pkt)
    elif linktype == LINKTYPE_BLE_LL:
        yield from _ble_ll(pkt)
    elif linktype == LINKTYPE_BLE_LL_PHDR and len(pkt) >= 10:
        flags = struct.unpack_from("<H", pkt, 8)[0]
        if flags & 0x0400 and not flags & 0x0800:  # CRC checked and wrong
            return
        yield from _ble_ll(pkt[10:])
    elif linktype == LINKTYPE_NORDIC_BLE:
        yield from _nordic(pkt)


def _odid(counter_and_msg: bytes) -> tuple[int, bytes]:
    """Split the counter byte off and cut the message (pack) to its own length."""
    counter, msg = counter_and_msg[0], counter_and_msg[1:]
    if msg and msg[0] >> 4 == 0xF and len(msg) >= 3:
        return counter, msg[:3 + MESSAGE_SIZE * msg[2]]
    return counter, msg[:MESSAGE_SIZE]


def _guarded(found: Iterator[tuple[datetime | None, int, bytes]]) -> Iterator[tuple[datetime | None, int, bytes]]:
    """The container parser's packets; anything it raises on a malformed file that is not
    already a CaptureError (struct.error, IndexError, ValueError, OverflowError) becomes one."""
    n = 0
    while True:
        n += 1
        try:
            item = next(found)
        except StopIteration:
            return
        except CaptureError:
            raise
        except (struct.error, IndexError, ValueError, OverflowError, KeyError) as exc:
            raise CaptureError(f"packet {n}: malformed container ({type(exc).__name__})") from None
        yield item


def extract(data: bytes, window: tuple[datetime, datetime] | None = None) -> list[CapturedMessage]:
    """Every Open Drone ID payload in the bytes of a pcap/pcapng file, in capture order; with
    `window` (first, last), only those of packets captured in it (the others' framing is still
    checked, their payloads are not decoded: a long capture costs little beyond a dwell's)."""
    out = []
    for frame_no, (ts, linktype, pkt) in enumerate(_guarded(packets(data)), start=1):
        if window is not None and (ts is None or not window[0] <= ts <= window[1]):
            continue
        try:
            for transport, payload, sender in _payloads(linktype, pkt):
                counter, raw = _odid(payload)
                out.append(CapturedMessage(frame=frame_no, captured_at=ts, transport=transport,
                                           counter=counter, message=decode(raw), sender=sender, raw=bytes(raw)))
        except CaptureError:
            raise
        except RemoteIdError as exc:
            raise CaptureError(f"packet {frame_no}: {exc}") from None
        except (struct.error, IndexError, ValueError, OverflowError):
            raise CaptureError(f"packet {frame_no}: malformed frame") from None
    return out


def read_capture(path: str | Path, window: tuple[datetime, datetime] | None = None) -> list[CapturedMessage]:
    """`extract` of a file (`window`: as there); unreadable or malformed files raise CaptureError.

    Only regular files are read (stat first): a FIFO or device would block or never end.
    """
    try:
        regular = stat.S_ISREG(os.stat(path).st_mode)
        data = Path(path).read_bytes() if regular else b""
    except (OSError, ValueError) as exc:  # ValueError: a NUL byte in the path
        raise CaptureError(f"{path}: cannot read ({getattr(exc, 'strerror', None) or exc})") from None
    if not regular:
        raise CaptureError(f"{path}: not a regular file (directory, FIFO, socket or device)")
    try:
        return extract(data, window)
    except CaptureError as exc:
        raise CaptureError(f"{path}: {exc}") from None


# ------------------------------------------------------------------ claims of a capture
#: Messages heard this long before the dwell's first chirp or after its last one still belong to it
#: (a Location is broadcast at >= 1 Hz: the window holds several); the clock-skew tolerance is added.
WINDOW_MARGIN_S = 5.0
#: Default tolerance for the sniffer's clock against the radar's (`--rid-skew`)
DEFAULT_SKEW_S = 2.0


@dataclass(frozen=True)
class Broadcaster:
    """One drone heard in a capture during a dwell: its UAS ID and its single messages."""

    uas_id: str
    senders: tuple[str, ...]
    rows: tuple[bytes, ...]  # 25-byte messages, in capture order
    heard_s: tuple[float, ...]  # when each was heard, seconds after the dwell's start
    #: conflicting transmitters (this UAS ID sent by two of them, or by one that sent another UAS ID
    #: of the same ID type too): each of its transmitters with every UAS ID it sent; () when none
    conflict: tuple[tuple[str, tuple[str, ...]], ...] = ()


def window(start: datetime, end: datetime, skew_s: float = DEFAULT_SKEW_S) -> tuple[datetime, datetime]:
    """The capture times that belong to a dwell from `start` to `end`: WINDOW_MARGIN_S and the
    clock-skew tolerance on either side."""
    margin = timedelta(seconds=WINDOW_MARGIN_S + max(skew_s, 0.0))
    return start - margin, end + margin


def broadcasters(captured: list[CapturedMessage], start: datetime, end: datetime,
                 skew_s: float = DEFAULT_SKEW_S) -> tuple[list[Broadcaster], int]:
    """The drones heard in [start - margin - skew, end + margin + skew], grouped by UAS ID, and
    how many messages in that window could not be attributed to one.

    A payload belongs to the UAS ID of a Basic ID in the same pack, else to the one its
    transmitter (Wi-Fi source address, BLE AdvA) sent anywhere in `captured` (what was read:
    `window` below). A transmitter that sent no Basic ID there cannot be attributed: its
    messages are counted, not guessed. Nor can one that sent two UAS IDs of one ID type (two
    drones behind one address; one drone may send a Basic ID per ID type): only its Basic IDs
    are attributed, each to its own UAS ID, and its other messages (Locations) are counted. A
    UAS ID sent by two transmitters, or by such a one, carries `conflict`."""
    from core.uasid import as_heard
    from remoteid.codec import split_raw
    from remoteid.messages import BasicId, MessagePack

    def basic_ids(c: CapturedMessage) -> list[BasicId]:
        msgs = c.message.messages if isinstance(c.message, MessagePack) else [c.message]
        return [m for m in msgs if isinstance(m, BasicId) and m.uas_id and m.uas_id.strip()]

    by_sender: dict[str, str] = {}
    sent: dict[str, dict[int, set[str]]] = {}  # transmitter -> ID type -> the UAS IDs it sent
    for c in captured:
        ids = basic_ids(c)
        if ids and c.sender is not None:
            by_sender.setdefault(c.sender, as_heard(ids[0].uas_id))
            for m in ids:
                sent.setdefault(c.sender, {}).setdefault(m.id_type, set()).add(as_heard(m.uas_id))
    ambiguous = {s for s, types in sent.items() if any(len(ids) > 1 for ids in types.values())}
    lo, hi = window(start, end, skew_s)
    groups: dict[str, tuple[set[str], list[bytes], list[float]]] = {}
    unattributed = 0

    def add(uas: str, sender: str | None, rows: list[bytes], t: float) -> None:
        senders, kept, heard = groups.setdefault(uas, (set(), [], []))
        if sender:
            senders.add(sender)
        kept.extend(rows)
        heard.extend([t] * len(rows))

    for c in captured:
        if c.captured_at is None or not lo <= c.captured_at <= hi:
            continue
        t = (c.captured_at - start).total_seconds()
        singles = split_raw(c.raw) if c.raw else []
        if c.sender in ambiguous:  # each Basic ID names its own drone; nothing else can be attributed
            for single, row in zip(c.message.messages if isinstance(c.message, MessagePack) else [c.message],
                                   singles):
                if isinstance(single, BasicId) and single.uas_id and single.uas_id.strip():
                    add(as_heard(single.uas_id), c.sender, [row], t)
                else:
                    unattributed += 1
            continue
        ids = basic_ids(c)
        uas = as_heard(ids[0].uas_id) if ids else by_sender.get(c.sender or "")
        if uas is None:
            unattributed += len(singles)
            continue
        add(uas, c.sender, singles, t)

    def conflict(senders: set[str]) -> tuple[tuple[str, tuple[str, ...]], ...]:
        if len(senders) < 2 and not senders & ambiguous:
            return ()
        return tuple((s, tuple(sorted(set().union(*sent.get(s, {}).values())))) for s in sorted(senders))

    return [Broadcaster(uas_id=u, senders=tuple(sorted(s)), rows=tuple(r), heard_s=tuple(h), conflict=conflict(s))
            for u, (s, r, h) in groups.items()], unattributed
