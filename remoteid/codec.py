"""ASTM F3411 wire codec: 25-byte messages and message packs <-> typed models.

Quantisation follows opendroneid-core-c (the reference implementation):
direction and the Location timestamp are rounded half away from zero (C
`roundf`); horizontal speed, vertical speed, latitude/longitude, altitudes and
the area radius are truncated toward zero (C integer casts). Latitude and
longitude are truncated from the exact decimal value of the float, so that a
decoded value re-encodes to the same bytes (the C double product can land a
hair below the integer). Reserved bits are ignored on decode and written as 0.
Imports only the standard library (the messages are `core.checked` dataclasses): `authn rid
decode` and a check start fast.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable, Iterable, Iterator
from datetime import datetime, timedelta, timezone
from typing import Any, TypeVar

from core.checked import Invalid
from remoteid.errors import RemoteIdError
from remoteid.messages import (
    SESSION_ID,
    ODID_EPOCH,
    AuthPage,
    AuthPage0,
    BasicId,
    Location,
    MessagePack,
    OperatorId,
    SelfId,
    Message,
    SingleMessage,
    System,
    _Message,
)

MESSAGE_SIZE = 25
PACK_MAX_MESSAGES = 9
MAX_PROTOCOL_VERSION = 2

TYPE_CODES: dict[str, int] = {
    "basic_id": 0x0, "location": 0x1, "auth": 0x2, "auth_page": 0x2,
    "self_id": 0x3, "system": 0x4, "operator_id": 0x5, "message_pack": 0xF,
}

_INV_DIR = 361
_INV_SPEED_H = 255  # raw value with the 0.75 m/s multiplier
_INV_SPEED_V = 126  # raw value: 63 m/s
_INV_TIMESTAMP = 0xFFFF
_MAX_TIMESTAMP = 36000  # tenths of a second in one hour

_LOCATION = struct.Struct("<BBBBbiiHHHBBHBB")
_SYSTEM = struct.Struct("<BBiiHBHHBHIB")
_AUTH0 = struct.Struct("<BBBBI17s")


# ---------------------------------------------------------------- helpers
def _round_half_away(x: float) -> int:
    """C `roundf`: halves go away from zero (Python's round() goes to even)."""
    return math.floor(x + 0.5) if x >= 0 else -math.floor(-x + 0.5)


_M = TypeVar("_M", bound=_Message)


def _build(cls: type[_M], what: str, **fields: Any) -> _M:
    try:
        return cls(**fields)
    except Invalid as exc:
        raise RemoteIdError(f"{what}: {exc.loc or what}: {exc.msg}") from None


def _text(raw: bytes, what: str) -> str:
    """NUL-padded ASCII field; bytes after the first NUL are padding."""
    raw = raw.split(b"\0", 1)[0]
    if any(b < 0x20 or b > 0x7E for b in raw):
        raise RemoteIdError(f"{what}: text field holds non-printable bytes {raw.hex()}")
    return raw.decode("ascii")


def _pad(text: str, size: int) -> bytes:
    return text.encode("ascii").ljust(size, b"\0")


def _dec_alt(raw: int) -> float | None:
    return None if raw == 0 else raw * 0.5 - 1000.0


def _enc_alt(alt: float | None) -> int:
    return 0 if alt is None else min(int((alt + 1000.0) / 0.5), 0xFFFF)


def _dec_latlon(lat_raw: int, lon_raw: int, what: str) -> tuple[float | None, float | None]:
    if lat_raw == 0 and lon_raw == 0:
        return None, None
    lat, lon = lat_raw / 1e7, lon_raw / 1e7
    if abs(lat) > 90 or abs(lon) > 180:
        raise RemoteIdError(f"{what}: latitude/longitude out of range ({lat}, {lon})")
    return lat, lon


def _enc_latlon(value: float | None) -> int:
    from decimal import Decimal  # encoding only (a decode, what a check does, never needs it)

    return 0 if value is None else int(Decimal(repr(value)) * 10_000_000)


def _dec_time(raw: int) -> datetime | None:
    return None if raw == 0 else ODID_EPOCH + timedelta(seconds=raw)


def _enc_time(value: datetime | None) -> int:
    if value is None:
        return 0
    return _round_half_away((value - ODID_EPOCH).total_seconds())


# ---------------------------------------------------------------- decode
def _decode_basic_id(b: bytes, ver: int) -> BasicId:
    id_type = b[1] >> 4
    return _build(BasicId, "basic ID", protocol_version=ver, id_type=id_type, ua_type=b[1] & 0xF,
                  uas_id=_session_id(b[2:22]) if id_type == SESSION_ID else _text(b[2:22], "basic ID"))


_DRIP_SESSION_BYTES = 17  # session ID type 1 (IETF DRIP) + a 16-byte DET


def _session_id(raw: bytes) -> str:
    """A binary session ID as hex: a DRIP one has a fixed length (its DET may end in zeros),
    any other is taken up to its NUL padding."""
    raw = raw[:_DRIP_SESSION_BYTES] if raw[:1] == b"\x01" else raw.rstrip(b"\0")
    return raw.hex().upper()


def _decode_location(b: bytes, ver: int) -> Location:
    (_, flags, direction, speed_h, speed_v, lat, lon, alt_baro, alt_geo, height,
     acc_hv, acc_bs, ts, ts_acc, _) = _LOCATION.unpack(b)
    direction += 180 if flags & 0x02 else 0
    if direction > 360 and direction != _INV_DIR:
        raise RemoteIdError(f"location: direction {direction} out of range")
    if flags & 0x01:
        speed = None if speed_h == _INV_SPEED_H else speed_h * 0.75 + 63.75
    else:
        speed = speed_h * 0.25
    if speed_v != _INV_SPEED_V and abs(speed_v) > 124:
        raise RemoteIdError(f"location: vertical speed {speed_v * 0.5} m/s out of range")
    if ts != _INV_TIMESTAMP and ts > _MAX_TIMESTAMP:
        raise RemoteIdError(f"location: timestamp {ts / 10} s is past the hour")
    latitude, longitude = _dec_latlon(lat, lon, "location")
    return _build(
        Location, "location", protocol_version=ver, status=flags >> 4,
        height_type=(flags >> 2) & 1,
        direction_deg=None if direction == _INV_DIR else float(direction),
        speed_horizontal_mps=speed,
        speed_vertical_mps=None if speed_v == _INV_SPEED_V else speed_v * 0.5,
        latitude_deg=latitude, longitude_deg=longitude,
        altitude_baro_m=_dec_alt(alt_baro), altitude_geo_m=_dec_alt(alt_geo),
        height_m=_dec_alt(height),
        horizontal_accuracy=acc_hv & 0xF, vertical_accuracy=acc_hv >> 4,
        baro_accuracy=acc_bs >> 4, speed_accuracy=acc_bs & 0xF,
        timestamp_s=None if ts == _INV_TIMESTAMP else ts / 10,
        timestamp_accuracy_s=(ts_acc & 0xF) / 10 or None,
    )


def _decode_auth(b: bytes, ver: int) -> AuthPage0 | AuthPage:
    page, auth_type = b[1] & 0xF, b[1] >> 4
    if page:
        return _build(AuthPage, "auth", protocol_version=ver, page=page,
                      auth_type=auth_type, data=bytes(b[2:25]))
    _, _, last, length, ts, data = _AUTH0.unpack(b)
    if last > 15:
        raise RemoteIdError(f"auth: last page index {last} out of range 0..15")
    return _build(AuthPage0, "auth", protocol_version=ver, auth_type=auth_type,
                  last_page_index=last, length=length, timestamp=_dec_time(ts), data=data)


def _decode_self_id(b: bytes, ver: int) -> SelfId:
    return _build(SelfId, "self ID", protocol_version=ver, desc_type=b[1],
                  description=_text(b[2:25], "self ID"))


def _decode_system(b: bytes, ver: int) -> System:
    (_, flags, lat, lon, count, radius, ceiling, floor, eu, op_alt, ts, _) = _SYSTEM.unpack(b)
    latitude, longitude = _dec_latlon(lat, lon, "system")
    v1 = ver >= 1
    return _build(
        System, "system", protocol_version=ver, operator_location_type=flags & 0x3,
        classification_type=(flags >> 2) & 0x7 if v1 else 0,
        operator_latitude_deg=latitude, operator_longitude_deg=longitude,
        area_count=count, area_radius_m=radius * 10,
        area_ceiling_m=_dec_alt(ceiling), area_floor_m=_dec_alt(floor),
        category_eu=eu >> 4 if v1 else 0, class_eu=eu & 0xF if v1 else 0,
        operator_altitude_geo_m=_dec_alt(op_alt) if v1 else None,
        timestamp=_dec_time(ts) if ver >= 2 else None,
    )


def _decode_operator_id(b: bytes, ver: int) -> OperatorId:
    return _build(OperatorId, "operator ID", protocol_version=ver, operator_id_type=b[1],
                  operator_id=_text(b[2:22], "operator ID"))


_DECODERS: dict[int, Callable[[bytes, int], SingleMessage]] = {
    0x0: _decode_basic_id, 0x1: _decode_location, 0x2: _decode_auth, 0x3: _decode_self_id, 0x4: _decode_system,
    0x5: _decode_operator_id}


def _header(data: bytes) -> tuple[int, int]:
    if not data:
        raise RemoteIdError("empty message")
    mtype, ver = data[0] >> 4, data[0] & 0xF
    if mtype not in _DECODERS and mtype != 0xF:
        raise RemoteIdError(f"unknown message type 0x{mtype:X} (header byte 0x{data[0]:02X})")
    if ver > MAX_PROTOCOL_VERSION:
        raise RemoteIdError(f"unsupported protocol version {ver} (0..{MAX_PROTOCOL_VERSION})")
    return mtype, ver


def _decode_single(data: bytes) -> SingleMessage:
    mtype, ver = _header(data)
    if mtype == 0xF:
        raise RemoteIdError("a message pack cannot contain a message pack")
    if len(data) != MESSAGE_SIZE:
        raise RemoteIdError(_size_msg(len(data)))
    return _DECODERS[mtype](data, ver)


def _size_msg(n: int) -> str:
    word = "truncated" if n < MESSAGE_SIZE else "over-long"
    return f"{word} message: {n} bytes, a Remote ID message has {MESSAGE_SIZE}"


def _decode_pack(data: bytes, ver: int) -> MessagePack:
    if len(data) < 3:
        raise RemoteIdError(f"truncated message pack: {len(data)} bytes")
    size, count = data[1], data[2]
    if size != MESSAGE_SIZE:
        raise RemoteIdError(f"message pack: single-message size {size}, expected {MESSAGE_SIZE}")
    if count > PACK_MAX_MESSAGES:
        raise RemoteIdError(f"message pack: {count} messages, at most {PACK_MAX_MESSAGES}")
    want = 3 + MESSAGE_SIZE * count
    if len(data) != want:
        word = "truncated" if len(data) < want else "over-long"
        raise RemoteIdError(f"{word} message pack: {len(data)} bytes, {count} messages need {want}")
    msgs = [_decode_single(data[i:i + MESSAGE_SIZE]) for i in range(3, want, MESSAGE_SIZE)]
    return MessagePack(protocol_version=ver, messages=msgs)


def decode(data: bytes | bytearray | memoryview) -> Message:
    """One message (25 bytes) or a message pack (3 + 25 n bytes) -> typed model.

    Raises RemoteIdError, and nothing else, for any input.
    """
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise RemoteIdError(f"expected bytes, got {type(data).__name__}")
    data = bytes(data)
    mtype, ver = _header(data)
    if mtype == 0xF:
        return _decode_pack(data, ver)
    return _decode_single(data)


def decode_hex(text: str) -> Message:
    """`decode` of a hex string (spaces, colons and a 0x prefix allowed)."""
    clean = text.strip().lower().removeprefix("0x").replace(":", "").replace(" ", "")
    try:
        return decode(bytes.fromhex(clean))
    except ValueError as exc:
        if isinstance(exc, RemoteIdError):
            raise
        raise RemoteIdError(f"not hex: {text[:60]!r}") from None


def _decoded_rows(rows: Iterable) -> Iterator[tuple[bytes, object]]:
    """(wire bytes, decoded message) of each row; all-zero rows are padding and skipped."""
    for i, row in enumerate(rows):
        try:
            raw = bytes(bytearray(row))
        except (TypeError, ValueError):
            raise RemoteIdError(f"row {i}: not a row of bytes (0..255)") from None
        if not any(raw):
            continue
        try:
            yield raw, decode(raw)
        except RemoteIdError as exc:
            raise RemoteIdError(f"row {i}: {exc}") from None


def decode_rows(rows: Iterable) -> list:
    """Decode each row of an (n, 25) uint8 array (or any iterable of byte rows).

    Rows that are all zero are padding and skipped. Used for the Remote ID
    messages embedded in a recorded return.
    """
    return [msg for _, msg in _decoded_rows(rows)]


def split_raw(data: bytes | bytearray | memoryview) -> list[bytes]:
    """The 25-byte wire form of each single message in `data` (one message or a pack).

    Same order as `flatten([decode(data)])`; raises RemoteIdError where `decode` would.
    """
    msg = decode(data)
    data = bytes(data)
    if isinstance(msg, MessagePack):
        return [data[i:i + MESSAGE_SIZE] for i in range(3, 3 + MESSAGE_SIZE * len(msg.messages), MESSAGE_SIZE)]
    return [data]


def decode_rows_raw(rows: Iterable) -> list[tuple]:
    """`flatten(decode_rows(rows))` with each single message paired with its 25 wire bytes.

    The pairs are `(message, raw)`; the signed Remote ID checks (DRIP) need the bytes
    as sent, not a re-encoding. Raises RemoteIdError exactly where `decode_rows` does.
    """
    out: list[tuple] = []
    for raw, msg in _decoded_rows(rows):
        if isinstance(msg, MessagePack):
            out.extend(zip(msg.messages, split_raw(raw)))
        else:
            out.append((msg, raw))
    return out


def flatten(messages: Iterable[Message]) -> list[SingleMessage]:
    """Single messages, with message packs expanded in place."""
    out: list[SingleMessage] = []
    for m in messages:
        out.extend(m.messages if isinstance(m, MessagePack) else [m])
    return out


# ---------------------------------------------------------------- encode
def _head(msg: Message) -> int:
    return TYPE_CODES[msg.type] << 4 | msg.protocol_version


def _encode_location(m: Location) -> bytes:
    flags = m.status << 4 | m.height_type << 2
    if m.direction_deg is None:
        direction = _INV_DIR
    else:
        direction = _round_half_away(m.direction_deg)
    if direction >= 180:
        flags |= 0x02
        direction -= 180
    s = m.speed_horizontal_mps
    if s is None:
        flags |= 0x01
        speed = _INV_SPEED_H
    elif s <= 63.75:
        speed = int(s / 0.25)
    else:
        flags |= 0x01
        speed = min(int((s - 63.75) / 0.75), 254)
    v = m.speed_vertical_mps
    return _LOCATION.pack(
        _head(m), flags, direction, speed,
        _INV_SPEED_V if v is None else int(v / 0.5),
        _enc_latlon(m.latitude_deg), _enc_latlon(m.longitude_deg),
        _enc_alt(m.altitude_baro_m), _enc_alt(m.altitude_geo_m), _enc_alt(m.height_m),
        m.vertical_accuracy << 4 | m.horizontal_accuracy,
        m.baro_accuracy << 4 | m.speed_accuracy,
        _INV_TIMESTAMP if m.timestamp_s is None else _round_half_away(m.timestamp_s * 10),
        0 if m.timestamp_accuracy_s is None else _round_half_away(m.timestamp_accuracy_s * 10),
        0,
    )


def _encode_system(m: System) -> bytes:
    return _SYSTEM.pack(
        _head(m), m.classification_type << 2 | m.operator_location_type,
        _enc_latlon(m.operator_latitude_deg), _enc_latlon(m.operator_longitude_deg),
        m.area_count, m.area_radius_m // 10,
        _enc_alt(m.area_ceiling_m), _enc_alt(m.area_floor_m),
        m.category_eu << 4 | m.class_eu, _enc_alt(m.operator_altitude_geo_m),
        _enc_time(m.timestamp), 0,
    )


def encode(msg: _Message) -> bytes:
    """Typed model -> wire bytes (25, or 3 + 25 n for a message pack)."""
    if isinstance(msg, BasicId):
        uas_id = bytes.fromhex(msg.uas_id).ljust(20, b"\0") if msg.id_type == SESSION_ID else _pad(msg.uas_id, 20)
        return bytes([_head(msg), msg.id_type << 4 | msg.ua_type]) + uas_id + bytes(3)
    if isinstance(msg, Location):
        return _encode_location(msg)
    if isinstance(msg, AuthPage0):
        return _AUTH0.pack(_head(msg), msg.auth_type << 4, msg.last_page_index, msg.length,
                           _enc_time(msg.timestamp), msg.data)
    if isinstance(msg, AuthPage):
        return bytes([_head(msg), msg.auth_type << 4 | msg.page]) + msg.data
    if isinstance(msg, SelfId):
        return bytes([_head(msg), msg.desc_type]) + _pad(msg.description, 23)
    if isinstance(msg, System):
        return _encode_system(msg)
    if isinstance(msg, OperatorId):
        return bytes([_head(msg), msg.operator_id_type]) + _pad(msg.operator_id, 20) + bytes(3)
    if isinstance(msg, MessagePack):
        return bytes([_head(msg), MESSAGE_SIZE, len(msg.messages)]) + b"".join(
            encode(m) for m in msg.messages)
    raise RemoteIdError(f"cannot encode {type(msg).__name__}")


def location_time(msg: Location, reference: datetime) -> datetime | None:
    """Absolute UTC time of a Location timestamp (seconds after the hour).

    The hour comes from `reference` (e.g. the capture time); the nearest of the
    previous, same and next hour is chosen so that clock skew across an hour
    boundary does not shift the result by an hour.
    """
    if msg.timestamp_s is None:
        return None
    ref = reference.astimezone(timezone.utc)
    hour = ref.replace(minute=0, second=0, microsecond=0)
    cands = [hour + timedelta(hours=k, seconds=msg.timestamp_s) for k in (-1, 0, 1)]
    return min(cands, key=lambda t: abs((t - ref).total_seconds()))
