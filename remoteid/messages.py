"""Typed ASTM F3411 broadcast messages in physical units.

Fields use SI-ish units (degrees, metres, m/s, seconds, UTC datetimes); a field
the sender marked "unknown" (speed 255, altitude -1000 m, direction 361,
lat/lon 0/0, timestamp 0xFFFF...) is `None`. Enumerated fields keep the wire
code as an int so that values reserved today still round-trip.
"""

from __future__ import annotations

import re

from datetime import datetime, timezone
from typing import Annotated, Literal, Union

from pydantic import BaseModel, ConfigDict, Field, model_validator

#: Epoch of the Authentication and System message timestamps.
ODID_EPOCH = datetime(2019, 1, 1, tzinfo=timezone.utc)
#: Highest encodable altitude (uint16 * 0.5 - 1000).
MAX_ALT_M = 31767.5
MIN_ALT_M = -1000.0

Nibble = Annotated[int, Field(ge=0, le=15)]
Byte = Annotated[int, Field(ge=0, le=255)]
Version = Annotated[int, Field(ge=0, le=2)]
Altitude = Annotated[float, Field(ge=MIN_ALT_M, le=MAX_ALT_M, allow_inf_nan=False)]
Latitude = Annotated[float, Field(ge=-90.0, le=90.0, allow_inf_nan=False)]
Longitude = Annotated[float, Field(ge=-180.0, le=180.0, allow_inf_nan=False)]
UtcTime = Annotated[datetime, Field(ge=ODID_EPOCH, le=datetime(2155, 2, 7, 6, 28, 15, tzinfo=timezone.utc))]


def _ascii(max_len: int):
    """Printable-ASCII text field of at most `max_len` bytes (NUL-padded on the wire)."""
    return Annotated[str, Field(max_length=max_len, pattern=r"^[\x20-\x7e]*$")]


class _Message(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid", ser_json_bytes="hex", val_json_bytes="hex",
                              defer_build=True)  # a check builds only the types it meets

    protocol_version: Version = 2


#: F3411 UAS ID type 4: a Specific Session ID, binary (first byte: the session ID type; 1 is IETF
#: DRIP, followed by the 16-byte DET of RFC 9374). Shown as upper-case hex, as the registry keys it.
SESSION_ID = 4
_PRINTABLE = re.compile(r"[\x20-\x7e]{0,20}")
_SESSION_HEX = re.compile(r"(?:[0-9A-F]{2}){1,20}")


class BasicId(_Message):
    """Type 0x0: who the aircraft is (ID type 1 serial, 2 CAA, 3 UTM UUID, 4 session).

    `uas_id` is the 20-byte field's text (NUL padding removed) for types 0-3, and the
    session ID as upper-case hex for type 4 (binary on the wire)."""

    type: Literal["basic_id"] = "basic_id"
    id_type: Nibble = 1
    ua_type: Nibble = 0
    uas_id: Annotated[str, Field(max_length=40)] = ""

    @model_validator(mode="after")
    def _uas_id_form(self) -> "BasicId":
        if self.id_type == SESSION_ID:
            if not self.uas_id:
                return self
            if not _SESSION_HEX.fullmatch(self.uas_id) or self.uas_id.startswith("00"):
                raise ValueError("a session ID (ID type 4) is 1-20 bytes as upper-case hex, "
                                 "the first (its type) not 00")
            if self.uas_id.startswith("01") and len(self.uas_id) != 34:
                raise ValueError("a DRIP session ID (type 01) is 17 bytes: 01 and a 16-byte DET")
            if not self.uas_id.startswith("01") and self.uas_id.endswith("00"):
                raise ValueError("a session ID cannot end in 00 (the field's padding)")
        elif not _PRINTABLE.fullmatch(self.uas_id):
            raise ValueError("a UAS ID is at most 20 printable ASCII characters")
        return self


class Location(_Message):
    """Type 0x1: where it is and how it moves."""

    type: Literal["location"] = "location"
    status: Nibble = 0
    height_type: Literal[0, 1] = 0
    direction_deg: Annotated[float, Field(ge=0.0, le=360.0, allow_inf_nan=False)] | None = None
    speed_horizontal_mps: Annotated[float, Field(ge=0.0, le=254.25, allow_inf_nan=False)] | None = None
    speed_vertical_mps: Annotated[float, Field(ge=-62.0, le=62.0, allow_inf_nan=False)] | None = None
    latitude_deg: Latitude | None = None
    longitude_deg: Longitude | None = None
    altitude_baro_m: Altitude | None = None
    altitude_geo_m: Altitude | None = None
    height_m: Altitude | None = None
    horizontal_accuracy: Nibble = 0
    vertical_accuracy: Nibble = 0
    baro_accuracy: Nibble = 0
    speed_accuracy: Nibble = 0
    #: Seconds after the full UTC hour (0.1 s steps).
    timestamp_s: Annotated[float, Field(ge=0.0, le=3600.0, allow_inf_nan=False)] | None = None
    timestamp_accuracy_s: Annotated[float, Field(ge=0.1, le=1.5)] | None = None

    @model_validator(mode="after")
    def _position_pair(self) -> "Location":
        if (self.latitude_deg is None) != (self.longitude_deg is None):
            raise ValueError("latitude and longitude are both known or both unknown")
        return self


class AuthPage0(_Message):
    """Type 0x2, page 0: authentication header and the first 17 data bytes."""

    type: Literal["auth"] = "auth"
    page: Literal[0] = 0
    auth_type: Nibble = 0
    last_page_index: Nibble = 0
    length: Byte = 0
    timestamp: UtcTime | None = None
    data: Annotated[bytes, Field(min_length=17, max_length=17)] = bytes(17)


class AuthPage(_Message):
    """Type 0x2, pages 1..15: 23 more authentication data bytes."""

    type: Literal["auth_page"] = "auth_page"
    page: Annotated[int, Field(ge=1, le=15)] = 1
    auth_type: Nibble = 0
    data: Annotated[bytes, Field(min_length=23, max_length=23)] = bytes(23)


class SelfId(_Message):
    """Type 0x3: free-text description of the flight."""

    type: Literal["self_id"] = "self_id"
    desc_type: Byte = 0
    description: _ascii(23) = ""


class System(_Message):
    """Type 0x4: operator position, operating area, EU classification.

    Classification, EU category/class and operator altitude exist from protocol
    version 1, the timestamp from version 2; older versions reserve those bytes.
    """

    type: Literal["system"] = "system"
    operator_location_type: Annotated[int, Field(ge=0, le=3)] = 0
    classification_type: Annotated[int, Field(ge=0, le=7)] = 0
    operator_latitude_deg: Latitude | None = None
    operator_longitude_deg: Longitude | None = None
    area_count: Annotated[int, Field(ge=0, le=65535)] = 1
    area_radius_m: Annotated[int, Field(ge=0, le=2550, multiple_of=10)] = 0
    area_ceiling_m: Altitude | None = None
    area_floor_m: Altitude | None = None
    category_eu: Nibble = 0
    class_eu: Nibble = 0
    operator_altitude_geo_m: Altitude | None = None
    timestamp: UtcTime | None = None

    @model_validator(mode="after")
    def _version_fields(self) -> "System":
        if (self.operator_latitude_deg is None) != (self.operator_longitude_deg is None):
            raise ValueError("operator latitude and longitude are both known or both unknown")
        if self.protocol_version < 1 and (
            self.classification_type or self.category_eu or self.class_eu
            or self.operator_altitude_geo_m is not None
        ):
            raise ValueError("classification and operator altitude need protocol version >= 1")
        if self.protocol_version < 2 and self.timestamp is not None:
            raise ValueError("system timestamp needs protocol version 2")
        return self


class OperatorId(_Message):
    """Type 0x5: the operator's registration ID."""

    type: Literal["operator_id"] = "operator_id"
    operator_id_type: Byte = 0
    operator_id: _ascii(20) = ""


SingleMessage = Annotated[
    Union[BasicId, Location, AuthPage0, AuthPage, SelfId, System, OperatorId],
    Field(discriminator="type"),
]


class MessagePack(_Message):
    """Type 0xF: up to nine 25-byte messages in one frame (Wi-Fi, Bluetooth 5)."""

    type: Literal["message_pack"] = "message_pack"
    messages: Annotated[list[SingleMessage], Field(max_length=9)] = []


Message = Annotated[
    Union[BasicId, Location, AuthPage0, AuthPage, SelfId, System, OperatorId, MessagePack],
    Field(discriminator="type"),
]
