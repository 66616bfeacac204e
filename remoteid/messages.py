"""Typed ASTM F3411 broadcast messages in physical units.

Fields use SI-ish units (degrees, metres, m/s, seconds, UTC datetimes); a field
the sender marked "unknown" (speed 255, altitude -1000 m, direction 361,
lat/lon 0/0, timestamp 0xFFFF...) is `None`. Enumerated fields keep the wire
code as an int so that values reserved today still round-trip.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from datetime import datetime, timezone
from typing import Any, Union

from core.checked import Checked, Invalid, choice, integer, moment, number, text
from core.checked import data as octets

#: Epoch of the Authentication and System message timestamps.
ODID_EPOCH = datetime(2019, 1, 1, tzinfo=timezone.utc)
#: Last encodable Authentication/System timestamp (uint32 seconds after the epoch).
ODID_LAST = datetime(2155, 2, 7, 6, 28, 15, tzinfo=timezone.utc)
#: Highest encodable altitude (uint16 * 0.5 - 1000).
MAX_ALT_M = 31767.5
MIN_ALT_M = -1000.0


def _nibble(default: int = 0) -> Any:
    return integer(default, ge=0, le=15)


def _byte(default: int = 0) -> Any:
    return integer(default, ge=0, le=255)


def _altitude() -> Any:
    return number(None, ge=MIN_ALT_M, le=MAX_ALT_M, finite=True, optional=True)


def _utc_time() -> Any:
    return moment(None, ge=ODID_EPOCH, le=ODID_LAST, optional=True)


def _ascii(max_len: int) -> Any:
    """Printable-ASCII text field of at most `max_len` bytes (NUL-padded on the wire)."""
    return text("", max_length=max_len, pattern=r"^[\x20-\x7e]*$")


@dataclass(frozen=True, kw_only=True)
class _Message(Checked):
    """Checked on construction (`core.checked`): a field out of range raises `Invalid`."""

    protocol_version: int = integer(2, ge=0, le=2)


#: F3411 UAS ID type 4: a Specific Session ID, binary (first byte: the session ID type; 1 is IETF
#: DRIP, followed by the 16-byte DET of RFC 9374). Shown as upper-case hex, as the registry keys it.
SESSION_ID = 4
_PRINTABLE = re.compile(r"[\x20-\x7e]{0,20}")
_SESSION_HEX = re.compile(r"(?:[0-9A-F]{2}){1,20}")


@dataclass(frozen=True, kw_only=True)
class BasicId(_Message):
    """Type 0x0: who the aircraft is (ID type 1 serial, 2 CAA, 3 UTM UUID, 4 session).

    `uas_id` is the 20-byte field's text (NUL padding removed) for types 0-3, and the
    session ID as upper-case hex for type 4 (binary on the wire)."""

    type: str = choice("basic_id", default="basic_id")
    id_type: int = _nibble(1)
    ua_type: int = _nibble()
    uas_id: str = text("", max_length=40)

    def _check(self) -> None:
        if self.id_type == SESSION_ID:
            if not self.uas_id:
                return
            if not _SESSION_HEX.fullmatch(self.uas_id) or self.uas_id.startswith("00"):
                raise ValueError("a session ID (ID type 4) is 1-20 bytes as upper-case hex, "
                                 "the first (its type) not 00")
            if self.uas_id.startswith("01") and len(self.uas_id) != 34:
                raise ValueError("a DRIP session ID (type 01) is 17 bytes: 01 and a 16-byte DET")
            if not self.uas_id.startswith("01") and self.uas_id.endswith("00"):
                raise ValueError("a session ID cannot end in 00 (the field's padding)")
        elif not _PRINTABLE.fullmatch(self.uas_id):
            raise ValueError("a UAS ID is at most 20 printable ASCII characters")


@dataclass(frozen=True, kw_only=True)
class Location(_Message):
    """Type 0x1: where it is and how it moves."""

    type: str = choice("location", default="location")
    status: int = _nibble()
    height_type: int = choice(0, 1, default=0)
    direction_deg: float | None = number(None, ge=0.0, le=360.0, finite=True, optional=True)
    speed_horizontal_mps: float | None = number(None, ge=0.0, le=254.25, finite=True, optional=True)
    speed_vertical_mps: float | None = number(None, ge=-62.0, le=62.0, finite=True, optional=True)
    latitude_deg: float | None = number(None, ge=-90.0, le=90.0, finite=True, optional=True)
    longitude_deg: float | None = number(None, ge=-180.0, le=180.0, finite=True, optional=True)
    altitude_baro_m: float | None = _altitude()
    altitude_geo_m: float | None = _altitude()
    height_m: float | None = _altitude()
    horizontal_accuracy: int = _nibble()
    vertical_accuracy: int = _nibble()
    baro_accuracy: int = _nibble()
    speed_accuracy: int = _nibble()
    #: Seconds after the full UTC hour (0.1 s steps).
    timestamp_s: float | None = number(None, ge=0.0, le=3600.0, finite=True, optional=True)
    timestamp_accuracy_s: float | None = number(None, ge=0.1, le=1.5, optional=True)

    def _check(self) -> None:
        if (self.latitude_deg is None) != (self.longitude_deg is None):
            raise ValueError("latitude and longitude are both known or both unknown")


@dataclass(frozen=True, kw_only=True)
class AuthPage0(_Message):
    """Type 0x2, page 0: authentication header and the first 17 data bytes."""

    type: str = choice("auth", default="auth")
    page: int = choice(0, default=0)
    auth_type: int = _nibble()
    last_page_index: int = _nibble()
    length: int = _byte()
    timestamp: datetime | None = _utc_time()
    data: bytes = octets(bytes(17), min_length=17, max_length=17)


@dataclass(frozen=True, kw_only=True)
class AuthPage(_Message):
    """Type 0x2, pages 1..15: 23 more authentication data bytes."""

    type: str = choice("auth_page", default="auth_page")
    page: int = integer(1, ge=1, le=15)
    auth_type: int = _nibble()
    data: bytes = octets(bytes(23), min_length=23, max_length=23)


@dataclass(frozen=True, kw_only=True)
class SelfId(_Message):
    """Type 0x3: free-text description of the flight."""

    type: str = choice("self_id", default="self_id")
    desc_type: int = _byte()
    description: str = _ascii(23)


@dataclass(frozen=True, kw_only=True)
class System(_Message):
    """Type 0x4: operator position, operating area, EU classification.

    Classification, EU category/class and operator altitude exist from protocol
    version 1, the timestamp from version 2; older versions reserve those bytes.
    """

    type: str = choice("system", default="system")
    operator_location_type: int = integer(0, ge=0, le=3)
    classification_type: int = integer(0, ge=0, le=7)
    operator_latitude_deg: float | None = number(None, ge=-90.0, le=90.0, finite=True, optional=True)
    operator_longitude_deg: float | None = number(None, ge=-180.0, le=180.0, finite=True, optional=True)
    area_count: int = integer(1, ge=0, le=65535)
    area_radius_m: int = integer(0, ge=0, le=2550, multiple_of=10)
    area_ceiling_m: float | None = _altitude()
    area_floor_m: float | None = _altitude()
    category_eu: int = _nibble()
    class_eu: int = _nibble()
    operator_altitude_geo_m: float | None = _altitude()
    timestamp: datetime | None = _utc_time()

    def _check(self) -> None:
        if (self.operator_latitude_deg is None) != (self.operator_longitude_deg is None):
            raise ValueError("operator latitude and longitude are both known or both unknown")
        if self.protocol_version < 1 and (
            self.classification_type or self.category_eu or self.class_eu
            or self.operator_altitude_geo_m is not None
        ):
            raise ValueError("classification and operator altitude need protocol version >= 1")
        if self.protocol_version < 2 and self.timestamp is not None:
            raise ValueError("system timestamp needs protocol version 2")


@dataclass(frozen=True, kw_only=True)
class OperatorId(_Message):
    """Type 0x5: the operator's registration ID."""

    type: str = choice("operator_id", default="operator_id")
    operator_id_type: int = _byte()
    operator_id: str = _ascii(20)


#: The single messages (what a message pack holds).
SINGLE_MESSAGES = (BasicId, Location, AuthPage0, AuthPage, SelfId, System, OperatorId)
SingleMessage = Union[BasicId, Location, AuthPage0, AuthPage, SelfId, System, OperatorId]


@dataclass(frozen=True, kw_only=True)
class MessagePack(_Message):
    """Type 0xF: up to nine 25-byte messages in one frame (Wi-Fi, Bluetooth 5)."""

    type: str = choice("message_pack", default="message_pack")
    messages: list[SingleMessage] = field(default_factory=list)

    def _check(self) -> None:
        msgs = self.messages
        if not isinstance(msgs, (list, tuple)) or not all(isinstance(m, SINGLE_MESSAGES) for m in msgs):
            raise Invalid("messages", "Input should be a list of single messages", msgs)
        if len(msgs) > 9:
            raise Invalid("messages", f"List should have at most 9 items after validation, not {len(msgs)}", msgs)
        object.__setattr__(self, "messages", list(msgs))


Message = Union[BasicId, Location, AuthPage0, AuthPage, SelfId, System, OperatorId, MessagePack]
