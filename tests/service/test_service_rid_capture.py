"""POST /v1/checks with a `rid_capture` multipart field: one decision per drone the capture heard.

An upload is a track of one dwell: at the default targets one unsigned dwell decides neither way
on radar, and the M300 and M600 registered here are radar-confusable, so each drone whose capture,
target and kinematics agree is `inconclusive` (200) with exactly `UNDECIDED` as its reasons; a
forbid that refutes (a conflicting transmitter) makes it a reject."""

from __future__ import annotations


import pytest

from tests.registry_tools import register
from signatures.recording import write_recording
from tests.remoteid.capture_tools import BEACON, SERIAL, locations, merge_pcaps, radar_return, rewrite, site_and_scene

SECOND = "MFG1A9876543210"
UNDECIDED = ["radar-confusable-unsigned", "radar-inconclusive"]


@pytest.fixture(scope="module")
def capture_world(sqlite_db, tmp_path_factory):
    root = tmp_path_factory.mktemp("svc-ridcap")
    register(sqlite_db, (SERIAL, "m300"), (SECOND, "m600"))
    c, loc = locations(BEACON)[8]
    az = (loc.direction_deg + 80.0) % 360.0
    site, a = site_and_scene(loc, 400.0, az, "m300")
    _, b = site_and_scene(loc, 440.0, az, "m600")
    two = write_recording(radar_return(site, [a, b], c.captured_at), root / "two.h5")
    b_only = rewrite(BEACON, root / "b.pcap", shift_m=40.0, az_deg=az, uas_id=SECOND,
                     sender=bytes.fromhex("02aabbccddee"))
    far = rewrite(BEACON, root / "far.pcap", shift_m=40.0, az_deg=az, sender=bytes.fromhex("02aabbccddee"), dt_s=0.2)
    return {"two": two, "both": merge_pcaps(BEACON, b_only, root / "both.pcap"),
            "impostor": merge_pcaps(BEACON, far, root / "impostor.pcap")}  # A's serial from a second transmitter


def _files(ret, capture):
    return {"file": (ret.name, ret.read_bytes(), "application/x-hdf5"),
            "rid_capture": (capture.name, capture.read_bytes(), "application/vnd.tcpdump.pcap")}


def test_capture_field_gives_one_decision_per_drone(server, keys, capture_world) -> None:
    with server.client(keys.operator) as c:
        resp = c.post("/v1/checks", files=_files(capture_world["two"], capture_world["both"]))
        assert resp.status_code == 200, resp.text
        out = resp.json()
        entries = [c.get(f"/v1/audit/{o['audit_id']}").json() for o in out]
    assert isinstance(out, list) and {o["claim"]["serial"] for o in out} == {SERIAL, SECOND}
    assert all(o["decision"] == "inconclusive" and o["reasons"] == UNDECIDED for o in out)  # nothing refutes either
    assert {e["serial"] for e in entries} == {SERIAL, SECOND}
    assert {e["decision"] for e in entries} == {"inconclusive"}


def test_capture_field_with_serial_answers_one_object(server, keys, capture_world) -> None:
    with server.client(keys.operator) as c:
        resp = c.post("/v1/checks", files=_files(capture_world["two"], capture_world["both"]), data={"serial": SECOND})
    assert resp.status_code == 200 and resp.json()["claim"]["serial"] == SECOND


def test_a_serial_from_two_transmitters_is_a_conflict(server, keys, capture_world) -> None:
    with server.client(keys.operator) as c:
        resp = c.post("/v1/checks", files=_files(capture_world["two"], capture_world["impostor"]))
    assert resp.status_code == 200, resp.text
    out = resp.json()
    assert out["claim"]["serial"] == SERIAL and out["decision"] == "reject" and "remote-id-conflict" in out["reasons"]
    assert out["remote_id"]["transmitters"] == ["02:aa:bb:cc:dd:ee", "84:cc:a8:60:43:24"]
    assert [t["transmitter"] for t in out["remote_id"]["conflict"]] == out["remote_id"]["transmitters"]


def test_truncated_capture_is_400(server, keys, capture_world, tmp_path) -> None:
    cut = tmp_path / "cut.pcap"
    cut.write_bytes(capture_world["both"].read_bytes()[:1000])
    with server.client(keys.operator) as c:
        resp = c.post("/v1/checks", files=_files(capture_world["two"], cut))
    assert resp.status_code == 400 and "cut.pcap" in resp.json()["error"]
