"""F3411 codec: layout, sentinels, quantisation, round trips, bad input."""

from __future__ import annotations

import struct
from datetime import datetime, timezone

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from remoteid import (AuthPage, AuthPage0, BasicId, Location, MessagePack, OperatorId, RemoteIdError, SelfId, System,
                      decode, decode_hex, decode_rows, encode, flatten, location_time)

# ------------------------------------------------------------------ known vectors
BEACON_PACK = bytes.fromhex(
    "f0190500004d464731413031323334353637383900000000000050f610005c527ebcba251ba88cb4b60000aa0998"
    "08394100000a00300052656372656174696f6e616c00000000000000000000004004a485251b6edbb3b601003200"
    "000000150000000000000050004742522d4f502d31323341424344000000000000000000")


def test_real_pack_fields():
    pack = decode(BEACON_PACK)
    basic, loc, self_id, system, op = pack.messages
    assert basic == BasicId(protocol_version=0, id_type=0, ua_type=0, uas_id="MFG1A0123456789")
    assert (loc.latitude_deg, loc.longitude_deg) == (45.5457468, -122.9681496)
    assert (loc.direction_deg, loc.speed_horizontal_mps, loc.speed_vertical_mps) == (92.0, 20.5, None)
    assert (loc.altitude_baro_m, loc.altitude_geo_m, loc.height_m) == (None, 237.0, 100.0)
    assert (loc.horizontal_accuracy, loc.vertical_accuracy, loc.baro_accuracy, loc.speed_accuracy) == (9, 3, 4, 1)
    assert loc.timestamp_s == 0.0 and loc.timestamp_accuracy_s == 1.0
    assert self_id.description == "Recreational"
    assert (system.operator_latitude_deg, system.area_radius_m, system.area_count) == (45.5443876, 500, 1)
    assert op.operator_id == "GBR-OP-123ABCD"
    # reserved bytes (Basic ID 22-24, System byte 1 bit 2 and bytes 17-24 in v0) are ignored
    again = encode(pack)
    assert again[3:25] == BEACON_PACK[3:25] and again[25:28] == bytes(3)
    assert decode(again) == pack


def test_sentinels_decode_to_none_and_encode_back():
    loc = Location()
    raw = encode(loc)
    assert raw.hex() == "12" + "03" + "b5" + "ff" + "7e" + "00" * 8 + "00" * 6 + "0000" + "ffff" + "0000"
    assert raw[1] & 0x03 == 0x03  # EW flag (361 = 180 + 181) and speed multiplier (255 * 0.75)
    assert decode(raw) == loc


def test_quantisation_matches_reference_rounding():
    m = Location(direction_deg=179.5, speed_horizontal_mps=10.2, speed_vertical_mps=-1.7,
                 latitude_deg=12.34567899, longitude_deg=-0.00000019, altitude_geo_m=100.9,
                 timestamp_s=1234.56, timestamp_accuracy_s=0.3)
    d = decode(encode(m))
    assert d.direction_deg == 180.0  # roundf: halves away from zero
    assert d.speed_horizontal_mps == 10.0  # truncated to 0.25 m/s
    assert d.speed_vertical_mps == -1.5  # truncated toward zero to 0.5 m/s
    assert (d.latitude_deg, d.longitude_deg) == (12.3456789, -0.0000001)  # truncated to 1e-7 deg
    assert d.altitude_geo_m == 100.5  # truncated to 0.5 m
    assert d.timestamp_s == 1234.6 and d.timestamp_accuracy_s == 0.3
    fast = decode(encode(Location(speed_horizontal_mps=100.0)))
    assert fast.speed_horizontal_mps == 99.75  # 0.75 m/s steps above 63.75 m/s


def test_time_fields():
    t = datetime(2024, 5, 1, 12, 0, 7, tzinfo=timezone.utc)
    auth = decode(encode(AuthPage0(auth_type=1, last_page_index=2, length=40, timestamp=t, data=bytes(range(17)))))
    assert auth.timestamp == t and auth.data == bytes(range(17))
    sysm = decode(encode(System(timestamp=t, classification_type=1, category_eu=1, class_eu=2,
                                operator_altitude_geo_m=150.0, operator_latitude_deg=1.0,
                                operator_longitude_deg=2.0)))
    assert sysm.timestamp == t and sysm.class_eu == 2
    loc = Location(timestamp_s=3599.0)
    assert location_time(loc, datetime(2024, 5, 1, 13, 0, 2, tzinfo=timezone.utc)) == \
        datetime(2024, 5, 1, 12, 59, 59, tzinfo=timezone.utc)


def test_version_specific_system_fields():
    with pytest.raises(ValueError, match="protocol version 2"):
        System(protocol_version=1, timestamp=datetime(2024, 1, 1, tzinfo=timezone.utc))
    with pytest.raises(ValueError, match="version >= 1"):
        System(protocol_version=0, classification_type=1)
    raw = bytearray(encode(System(protocol_version=2, timestamp=datetime(2024, 1, 1, tzinfo=timezone.utc),
                                  class_eu=3)))
    raw[0] = 0x40  # the same bytes read as version 0: those fields are reserved there
    old = decode(bytes(raw))
    assert old.timestamp is None and old.class_eu == 0


@pytest.mark.parametrize("data, match", [
    (b"", "empty"),
    (bytes([0x02]) + bytes(23), "truncated message: 24 bytes"),
    (bytes([0x02]) + bytes(25), "over-long message: 26 bytes"),
    (bytes([0x62]) + bytes(24), "unknown message type 0x6"),
    (bytes([0xE0]) + bytes(24), "unknown message type 0xE"),
    (bytes([0x03]) + bytes(24), "unsupported protocol version 3"),
    (bytes([0xF2, 25, 10]) + bytes(250), "at most 9"),
    (bytes([0xF2, 24, 1]) + bytes(24), "single-message size 24"),
    (bytes([0xF2, 25, 2]) + bytes(25), "truncated message pack"),
    (bytes([0xF2, 25, 1]) + bytes(26), "over-long message pack"),
    (bytes([0xF2, 25, 1, 0xF2]) + bytes(24), "cannot contain a message pack"),
    (bytes([0x02, 0x12]) + b"ABC\x01" + bytes(19), "non-printable"),
    (bytes([0x12, 0x02, 200]) + bytes(22), "direction 380 out of range"),
    (bytes([0x12, 0, 0, 0, 127]) + bytes(20), "vertical speed"),
    (bytes([0x12]) + bytes(20) + struct.pack("<H", 36001) + bytes(2), "past the hour"),
    (bytes([0x12, 0, 0, 0, 0]) + struct.pack("<ii", 910000000, 1) + bytes(12), "latitude/longitude"),
    (bytes([0x22, 0x00, 16]) + bytes(22), "last page index 16"),
])
def test_bad_input_gets_a_specific_error(data, match):
    with pytest.raises(RemoteIdError, match=match):
        decode(data)


def test_hex_and_rows():
    raw = encode(BasicId(uas_id="1581F5FJD12345678901"))
    assert decode_hex("0x" + raw.hex().upper()) == decode(raw)
    assert decode_hex(" ".join(f"{b:02x}" for b in raw)) == decode(raw)
    with pytest.raises(RemoteIdError, match="not hex"):
        decode_hex("zz")
    rows = [list(raw), [0] * 25, list(encode(Location(latitude_deg=1.0, longitude_deg=2.0)))]
    assert [m.type for m in decode_rows(rows)] == ["basic_id", "location"]
    with pytest.raises(RemoteIdError, match="row 1"):
        decode_rows([list(raw), [0x70] + [0] * 24])
    with pytest.raises(RemoteIdError, match="row 0"):
        decode_rows([[300] * 25])
    assert [m.type for m in flatten([MessagePack(messages=[BasicId(), SelfId()]), Location()])] == \
        ["basic_id", "self_id", "location"]


def test_encode_rejects_what_it_cannot_represent():
    with pytest.raises(ValueError):
        BasicId(uas_id="X" * 21)
    with pytest.raises(ValueError):
        Location(speed_horizontal_mps=300.0)
    with pytest.raises(ValueError):
        Location(latitude_deg=1.0)  # longitude missing
    with pytest.raises(ValueError):
        System(area_radius_m=15)


# ------------------------------------------------------------------ property tests
text20 = st.text(st.characters(min_codepoint=0x20, max_codepoint=0x7E), max_size=20)
text23 = st.text(st.characters(min_codepoint=0x20, max_codepoint=0x7E), max_size=23)
ver = st.integers(0, 2)
nib = st.integers(0, 15)
alt = st.one_of(st.none(), st.floats(-999.5, 31767.5))
utc = st.one_of(st.none(), st.integers(1, 2**32 - 1).map(
    lambda s: datetime.fromtimestamp(1546300800 + s, tz=timezone.utc)))
coord = st.floats(1e-6, 90.0) | st.floats(-90.0, -1e-6)
lon_coord = st.floats(1e-6, 180.0) | st.floats(-180.0, -1e-6)


@st.composite
def locations(draw):
    pos = draw(st.booleans())
    return Location(
        protocol_version=draw(ver), status=draw(nib), height_type=draw(st.integers(0, 1)),
        direction_deg=draw(st.none() | st.floats(0, 360)),
        speed_horizontal_mps=draw(st.none() | st.floats(0, 254.25)),
        speed_vertical_mps=draw(st.none() | st.floats(-62, 62)),
        latitude_deg=draw(coord) if pos else None, longitude_deg=draw(lon_coord) if pos else None,
        altitude_baro_m=draw(alt), altitude_geo_m=draw(alt), height_m=draw(alt),
        horizontal_accuracy=draw(nib), vertical_accuracy=draw(nib), baro_accuracy=draw(nib),
        speed_accuracy=draw(nib), timestamp_s=draw(st.none() | st.floats(0, 3600)),
        timestamp_accuracy_s=draw(st.none() | st.integers(1, 15).map(lambda c: c / 10)))


@st.composite
def systems(draw):
    v = draw(ver)
    pos = draw(st.booleans())
    return System(
        protocol_version=v, operator_location_type=draw(st.integers(0, 3)),
        classification_type=draw(st.integers(0, 7)) if v else 0,
        operator_latitude_deg=draw(coord) if pos else None,
        operator_longitude_deg=draw(lon_coord) if pos else None,
        area_count=draw(st.integers(0, 65535)), area_radius_m=draw(st.integers(0, 255)) * 10,
        area_ceiling_m=draw(alt), area_floor_m=draw(alt),
        category_eu=draw(nib) if v else 0, class_eu=draw(nib) if v else 0,
        operator_altitude_geo_m=draw(alt) if v else None, timestamp=draw(utc) if v == 2 else None)


singles = st.one_of(
    st.builds(BasicId, protocol_version=ver, id_type=nib.filter(lambda t: t != 4), ua_type=nib, uas_id=text20),
    st.builds(BasicId, protocol_version=ver, id_type=st.just(4), ua_type=nib,
              uas_id=st.one_of(st.binary(min_size=16, max_size=16).map(lambda det: "01" + det.hex().upper()),
                               st.binary(min_size=1, max_size=19).filter(lambda b: b[0] > 1 and b[-1] != 0)
                               .map(lambda b: b.hex().upper()))),
    locations(),
    st.builds(AuthPage0, protocol_version=ver, auth_type=nib, last_page_index=nib,
              length=st.integers(0, 255), timestamp=utc, data=st.binary(min_size=17, max_size=17)),
    st.builds(AuthPage, protocol_version=ver, page=st.integers(1, 15), auth_type=nib,
              data=st.binary(min_size=23, max_size=23)),
    st.builds(SelfId, protocol_version=ver, desc_type=st.integers(0, 255), description=text23),
    systems(),
    st.builds(OperatorId, protocol_version=ver, operator_id_type=st.integers(0, 255), operator_id=text20),
)
messages = singles | st.builds(MessagePack, protocol_version=ver, messages=st.lists(singles, max_size=9))


def _close(orig, back) -> None:
    """`back` equals `orig` up to the documented quantisation."""
    if isinstance(orig, MessagePack):
        assert len(orig.messages) == len(back.messages)
        for a, b in zip(orig.messages, back.messages):
            _close(a, b)
        return
    for name, a in orig.to_dict().items():
        b = getattr(back, name)
        if a is None or isinstance(a, (str, bytes)) or name in ("protocol_version", "type"):
            assert b == a, name
        elif name == "direction_deg":
            assert abs(b - a) <= 0.5
        elif name == "speed_horizontal_mps":
            step = 0.25 if a <= 63.75 else 0.75
            assert b <= a + 1e-9 and a - b < step
        elif name == "speed_vertical_mps":
            assert abs(b) <= abs(a) and abs(a - b) < 0.5
        elif name.endswith("_deg"):
            assert abs(b) <= abs(a) and abs(a - b) < 1e-7 + 1e-12
        elif name.endswith("_m") and name != "area_radius_m":
            assert b is not None and b <= a + 1e-9 and a - b < 0.5  # float sum a + 1000
        elif name == "timestamp_s":
            assert abs(a - b) <= 0.05 + 1e-9
        elif isinstance(a, datetime):
            assert abs((a - b).total_seconds()) <= 0.5
        else:
            assert b == a, name


@settings(max_examples=300, deadline=None)
@given(messages)
def test_decode_encode_is_identity_up_to_quantisation(msg):
    _close(msg, decode(encode(msg)))


def _u16(draw):
    return draw(st.integers(0, 0xFFFF))


def _padded(draw, size):
    t = draw(st.text(st.characters(min_codepoint=0x20, max_codepoint=0x7E), max_size=size))
    return t.encode().ljust(size, b"\0")


@st.composite
def valid_wire(draw) -> bytes:
    """Canonical 25-byte messages: reserved bits 0, values in range, as the reference encodes."""
    v = draw(ver)
    kind = draw(st.sampled_from(["basic", "loc", "auth0", "auth", "self", "system", "op"]))
    if kind in ("basic", "op"):
        b1 = draw(st.integers(0, 255))
        return bytes([(0 if kind == "basic" else 5) << 4 | v, b1]) + _padded(draw, 20) + bytes(3)
    if kind == "self":
        return bytes([0x30 | v, draw(st.integers(0, 255))]) + _padded(draw, 23)
    if kind == "auth0":
        return struct.pack("<BBBBI", 0x20 | v, draw(nib) << 4, draw(nib), draw(st.integers(0, 255)),
                           draw(st.integers(0, 2**32 - 1))) + draw(st.binary(min_size=17, max_size=17))
    if kind == "auth":
        return bytes([0x20 | v, draw(nib) << 4 | draw(st.integers(1, 15))]) + draw(
            st.binary(min_size=23, max_size=23))
    if kind == "loc":
        ew, mult = draw(st.integers(0, 1)), draw(st.integers(0, 1))
        direction = draw(st.integers(0, 181 if ew else 179))
        speed = draw(st.integers(1, 255) if mult else st.integers(0, 255))
        flags = draw(nib) << 4 | draw(st.integers(0, 1)) << 2 | ew << 1 | mult
        return struct.pack(
            "<BBBBbiiHHHBBHBB", 0x10 | v, flags, direction, speed,
            draw(st.integers(-124, 124) | st.just(126)),
            draw(st.integers(-900_000_000, 900_000_000)), draw(st.integers(-1_800_000_000, 1_800_000_000)),
            _u16(draw), _u16(draw), _u16(draw), draw(st.integers(0, 255)), draw(st.integers(0, 255)),
            draw(st.integers(0, 36000) | st.just(0xFFFF)), draw(nib), 0)
    flags = (draw(st.integers(0, 7)) << 2 if v else 0) | draw(st.integers(0, 3))
    tail = struct.pack("<BHI", draw(st.integers(0, 255)), _u16(draw),
                       draw(st.integers(0, 2**32 - 1)) if v == 2 else 0) if v else bytes(7)
    return struct.pack(
        "<BBiiHBHH", 0x40 | v, flags, draw(st.integers(-900_000_000, 900_000_000)),
        draw(st.integers(-1_800_000_000, 1_800_000_000)), _u16(draw), draw(st.integers(0, 255)),
        _u16(draw), _u16(draw)) + tail + b"\0"


@settings(max_examples=500, deadline=None)
@given(valid_wire())
def test_encode_decode_is_identity_on_valid_messages(raw):
    assert len(raw) == 25
    assert encode(decode(raw)) == raw


@settings(max_examples=100, deadline=None)
@given(st.lists(valid_wire(), max_size=9), ver)
def test_pack_bytes_round_trip(msgs, v):
    raw = bytes([0xF0 | v, 25, len(msgs)]) + b"".join(msgs)
    assert encode(decode(raw)) == raw


@settings(max_examples=2000, deadline=None)
@given(st.binary(max_size=260) | st.binary(min_size=25, max_size=25)
       | st.binary(min_size=22, max_size=22).map(lambda b: bytes([0xF1, 25, 1]) + b + b"xyz"))
def test_decoder_raises_only_its_own_error(data):
    try:
        decode(data)
    except RemoteIdError:
        pass
