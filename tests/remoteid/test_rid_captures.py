"""Real over-the-air captures (tests/data/remoteid-captures, see its README for source and licence)."""

from __future__ import annotations

import json
import struct
import subprocess
import sys
from collections import Counter
from datetime import datetime, timezone
from pathlib import Path

import pytest

from authn.cli import main
from remoteid import CaptureError, flatten
from remoteid.capture import extract, read_capture

DATA = Path(__file__).resolve().parents[1] / "data" / "remoteid-captures"


def _utc(*a) -> datetime:
    return datetime(*a, tzinfo=timezone.utc)


def _singles(found, kind):
    return [(c, m) for c in found for m in flatten([c.message]) if m.type == kind]


def test_wifi_beacon_capture():
    found = read_capture(DATA / "odid_wifi_bcn_sample.pcap")
    assert len(found) == 21 and {c.transport for c in found} == {"wifi_beacon"}
    assert all(len(c.message.messages) == 5 for c in found)
    assert found[0].captured_at == _utc(2021, 5, 21, 21, 52, 11, 161999)
    assert found[-1].captured_at == _utc(2021, 5, 21, 21, 52, 25, 961949)
    assert {m.uas_id for _, m in _singles(found, "basic_id")} == {"MFG1A0123456789"}
    assert {m.id_type for _, m in _singles(found, "basic_id")} == {0}  # reserved bytes non-zero, ignored
    locs = [m for _, m in _singles(found, "location")]
    assert len(locs) == 21
    assert (locs[0].latitude_deg, locs[0].longitude_deg) == (45.5457468, -122.9681496)
    assert (locs[1].latitude_deg, locs[1].longitude_deg, locs[1].direction_deg) == (45.5457355, -122.9678163, 35.0)
    assert (locs[-1].latitude_deg, locs[-1].longitude_deg, locs[-1].direction_deg) == (45.5470818, -122.9668346, 280.0)
    assert all(m.altitude_geo_m == 237.0 and m.height_m == 100.0 and m.speed_horizontal_mps == 20.5
               and m.timestamp_s == 0.0 and m.altitude_baro_m is None for m in locs)
    system = _singles(found, "system")[0][1]
    assert (system.operator_latitude_deg, system.operator_longitude_deg) == (45.5443876, -122.9726866)
    assert {m.operator_id for _, m in _singles(found, "operator_id")} == {"GBR-OP-123ABCD"}
    assert {m.description for _, m in _singles(found, "self_id")} == {"Recreational"}


def test_wifi_nan_and_beacon_capture():
    found = read_capture(DATA / "odid_wifi_sample.pcap")
    # 63 frames: 21 NAN sync beacons (no Remote ID), 21 NAN service discovery frames, 21 beacons
    assert Counter(c.transport for c in found) == {"wifi_nan": 21, "wifi_beacon": 21}
    assert all(len(c.message.messages) == 1 for c in found)
    assert found[0].frame == 2 and found[-1].frame == 63
    assert found[0].captured_at == _utc(2021, 5, 12, 20, 3, 25, 193865)
    assert found[-1].captured_at == _utc(2021, 5, 12, 20, 3, 39, 994699)
    kinds = Counter(m.type for c in found for m in flatten([c.message]))
    assert kinds == {"location": 31, "self_id": 4, "system": 4, "operator_id": 3}
    locs = _singles(found, "location")
    first, last = locs[0], locs[-1]
    assert (first[0].frame, first[1].latitude_deg, first[1].longitude_deg) == (5, 45.5450519, -122.9722906)
    assert (last[0].frame, last[1].latitude_deg, last[1].longitude_deg) == (63, 45.5448998, -122.9722283)
    assert all(m.altitude_geo_m == 237.0 and m.speed_horizontal_mps == 20.5 for _, m in locs)
    assert {m.operator_id for _, m in _singles(found, "operator_id")} == {"GBR-OP-123ABCD"}


def test_bluetooth5_long_range_capture():
    found = read_capture(DATA / "odid_bt5_lr_sample.pcapng")
    # 274 packets, 30 with a failed CRC (skipped): 244 message packs
    assert len(found) == 244 and {c.transport for c in found} == {"bt_extended"}
    assert found[0].captured_at == _utc(2023, 10, 4, 3, 41, 57, 558003)
    assert found[-1].captured_at == _utc(2023, 10, 4, 3, 42, 15, 168293)
    assert found[-1].frame == 274
    counters = [c.counter for c in found]
    assert counters[:3] == [12, 13, 14]
    basic = _singles(found, "basic_id")
    assert len(basic) == 225 and {(m.uas_id, m.id_type, m.ua_type) for _, m in basic} == {
        ("SSEVTFG93700070", 1, 2)}
    assert {m.operator_id for _, m in _singles(found, "operator_id")} == {"FIN87astrdge12kxyz8"}
    assert {m.description for _, m in _singles(found, "self_id")} == {"Drone ID demo"}
    locs = [m for _, m in _singles(found, "location")]
    assert len(locs) == 222
    assert Counter((m.latitude_deg, m.status, m.altitude_baro_m, m.height_m, m.timestamp_s) for m in locs) == {
        (None, 2, -55.0, -0.5, 0.0): 168, (None, 2, -55.0, 0.0, 0.0): 50, (None, 2, -54.5, 0.0, 0.0): 4}


def test_rid_decode_pcap_cli(capsys):
    assert main(["rid", "decode", "--pcap", str(DATA / "odid_wifi_bcn_sample.pcap"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert len(out) == 21 and out[0]["transport"] == "wifi_beacon"
    assert out[0]["message"]["messages"][0]["uas_id"] == "MFG1A0123456789"
    assert main(["rid", "decode", "--pcap", str(DATA / "odid_bt5_lr_sample.pcapng")]) == 0
    out = capsys.readouterr().out
    assert len(out.splitlines()) == 1069 and "\tbt_extended\t" in out  # piped: one tab-separated line each


# ------------------------------------------------------------------ garbage and synthetic
def _pcap(linktype: int, packets: list[bytes], magic=b"\xd4\xc3\xb2\xa1") -> bytes:
    out = magic + struct.pack("<HHiIII", 2, 4, 0, 0, 65535, linktype)
    for i, p in enumerate(packets):
        out += struct.pack("<IIII", 1700000000 + i, 500, len(p), len(p)) + p
    return out


def test_bluetooth4_legacy_and_ble_ll(tmp_path):
    from remoteid import BasicId, encode

    msg = encode(BasicId(uas_id="1581F5FJD12345678901"))
    ad = bytes([30, 0x16, 0xFA, 0xFF, 0x0D, 7]) + msg
    pdu = bytes([0x02, 6 + len(ad)]) + bytes(6) + ad  # ADV_NONCONN_IND
    ll = struct.pack("<I", 0x8E89BED6) + pdu + bytes(3)
    found = extract(_pcap(251, [ll, b"\x00" * 3]))
    assert len(found) == 1 and found[0].transport == "bt_legacy" and found[0].counter == 7
    assert found[0].message.uas_id == "1581F5FJD12345678901"
    assert found[0].captured_at == datetime.fromtimestamp(1700000000, timezone.utc).replace(microsecond=500)
    phdr = bytes(8) + struct.pack("<H", 0x0C00)  # CRC checked and valid
    assert len(extract(_pcap(256, [phdr + ll]))) == 1
    bad_crc = bytes(8) + struct.pack("<H", 0x0400)
    assert extract(_pcap(256, [bad_crc + ll])) == []


@pytest.mark.parametrize("data, match", [
    (b"", "not a pcap"),
    (b"hello world, not a capture", "not a pcap"),
    (b"\xd4\xc3\xb2\xa1" + bytes(10), "truncated pcap header"),
    (_pcap(105, [b"\x80" * 40])[:-5], "corrupt record"),
    (_pcap(105, [b"x"]) + b"\x01\x02", "truncated record header"),
    (b"\x0a\x0d\x0d\x0a" + struct.pack("<I", 7) + b"\x4d\x3c\x2b\x1a", "corrupt block length"),
    (b"\x0a\x0d\x0d\x0a" + struct.pack("<I", 12) + b"\x00\x00\x00\x00", "byte-order magic"),
])
def test_garbage_captures_get_a_specific_error(data, match):
    with pytest.raises(CaptureError, match=match):
        extract(data)


def test_corrupt_odid_payload_names_the_packet():
    ie = b"\xdd\x1e\xfa\x0b\xbc\x0d\x01" + bytes([0x72]) + bytes(24)  # type 7: unknown
    frame = b"\x80\x00" + bytes(22) + bytes(12) + ie
    with pytest.raises(CaptureError, match="packet 1: unknown message type 0x7"):
        extract(_pcap(105, [frame]))


def test_rid_decode_cli_bad_input(tmp_path):
    garbage = tmp_path / "x.pcap"
    garbage.write_bytes(b"\xd4\xc3\xb2\xa1garbage")
    for args in (["rid", "decode", "--pcap", str(garbage)], ["rid", "decode", "12"],
                 ["rid", "decode", "nothex"], ["rid", "decode"],
                 ["rid", "decode", "--pcap", str(tmp_path / "missing.pcap")]):
        proc = subprocess.run([sys.executable, "-c", "import sys; from authn.cli import main; "
                               "sys.exit(main(sys.argv[1:]))", *args], capture_output=True, text=True)
        assert proc.returncode == 2, (args, proc.stderr)
        assert proc.stderr.startswith("error: ") and proc.stderr.count("\n") == 1, proc.stderr


def test_rid_decode_does_not_import_the_database_stack():
    code = ("import sys; from authn.cli import main; main(['rid', 'decode', '0012' + '00' * 23]); "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('sqlalchemy', 'alembic')))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert proc.stdout.strip().endswith("[]"), proc.stdout + proc.stderr
