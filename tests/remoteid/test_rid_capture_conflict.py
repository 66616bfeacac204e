"""Conflicting transmitters in a `--rid-capture` capture: a second transmitter sending the genuine
drone's serial from 40 m further out, and one transmitter sending two serials (two drones behind one
address, each message in its own beacon). Each claim they name is `remote-id-conflict`, every
transmitter is named in the JSON, nothing is merged silently, and no Location of a transmitter that
sent two serials is attributed to either. Real pcap bytes, simulated returns, the real CLI."""

from __future__ import annotations

import json
from datetime import timedelta

import pytest

from authn.cli import main
from tests.registry_tools import register
from remoteid import BasicId, decode, flatten
from remoteid.capture import broadcasters, read_capture
from remoteid.codec import split_raw
from signatures.recording import write_recording
from tests.remoteid.capture_tools import (BEACON, SERIAL, beacons, locations, merge_pcaps, radar_return, rewrite,
                                          site_and_scene)

SECOND = "MFG1A9876543210"
GENUINE_MAC, IMPOSTOR_MAC = "84:cc:a8:60:43:24", "02:aa:bb:cc:dd:ee"
NOT_CHECKED = "not checked: no Remote ID position"


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    root = tmp_path_factory.mktemp("ridconflict")
    db = f"sqlite:///{root / 'r.sqlite3'}"
    register(db, (SERIAL, "m300"), (SECOND, "m600"))
    c, loc = locations(BEACON)[8]
    az = (loc.direction_deg + 80.0) % 360.0
    site, scene_a = site_and_scene(loc, 400.0, az, "m300")
    _, scene_b = site_and_scene(loc, 440.0, az, "m600")  # a second target 40 m further out
    two = write_recording(radar_return(site, [scene_a, scene_b], c.captured_at), root / "two.h5")
    # (a) an impostor: the genuine serial, from another transmitter, positions 40 m further out
    far = rewrite(BEACON, root / "far.pcap", shift_m=40.0, az_deg=az, sender=bytes.fromhex("02aabbccddee"),
                  dt_s=0.2)
    impostor = merge_pcaps(BEACON, far, root / "impostor.pcap")
    # (b) two drones on one transmitter, every message in its own beacon (Locations apart from Basic IDs)
    second = rewrite(BEACON, root / "second.pcap", shift_m=40.0, az_deg=az, uas_id=SECOND)
    mac = bytes.fromhex(GENUINE_MAC.replace(":", ""))
    frames = []
    for a, b in zip(read_capture(BEACON), read_capture(second)):
        frames += [(a.captured_at, mac, row) for row in split_raw(a.raw)]
        frames += [(b.captured_at + timedelta(seconds=0.05), mac, row) for row in split_raw(b.raw)]
    shared = beacons(root / "shared.pcap", frames)
    return {"db": db, "root": root, "two": two, "impostor": impostor, "shared": shared}


def _check(w, capsys, *args: str) -> tuple[int, object]:
    capsys.readouterr()
    code = main(["--db", w["db"], "check", "--json", *args])
    out = capsys.readouterr().out
    return code, json.loads(out) if out.strip() else None


def test_a_second_transmitter_of_the_genuine_serial_is_a_conflict(world, capsys):
    code, out = _check(world, capsys, str(world["two"]), "--rid-capture", str(world["impostor"]))
    assert code == 1 and isinstance(out, dict) and out["claim"]["serial"] == SERIAL
    assert out["decision"] != "accept" and "remote-id-conflict" in out["reasons"]
    assert out["remote_id"]["transmitters"] == [IMPOSTOR_MAC, GENUINE_MAC]  # both, never merged silently
    assert out["remote_id"]["conflict"] == [{"transmitter": IMPOSTOR_MAC, "serials": [SERIAL]},
                                            {"transmitter": GENUINE_MAC, "serials": [SERIAL]}]
    assert out["radar"] is None  # decided before any radar work
    # the genuine capture alone: one transmitter, no conflict
    code, out = _check(world, capsys, str(world["two"]), "--rid-capture", str(BEACON))
    assert "remote-id-conflict" not in out["reasons"] and out["remote_id"]["transmitters"] == [GENUINE_MAC]
    assert "conflict" not in out["remote_id"]


def test_two_serials_from_one_transmitter_conflict_for_both(world, capsys):
    code, out = _check(world, capsys, str(world["two"]), "--rid-capture", str(world["shared"]))
    assert code == 1 and isinstance(out, list) and {o["claim"]["serial"] for o in out} == {SERIAL, SECOND}
    for o in out:
        assert o["decision"] != "accept" and "remote-id-conflict" in o["reasons"], o["reasons"]
        assert o["remote_id"]["conflict"] == [{"transmitter": GENUINE_MAC, "serials": sorted([SERIAL, SECOND])}]
        # no Location attributed to either serial: no position, nothing to compare with the radar
        assert o["claim"]["position"] == NOT_CHECKED and o["kinematics"] is None
        assert "remote-id-no-location" in o["reasons"]


def test_broadcasters_attribute_no_location_of_a_shared_transmitter(world):
    captured = read_capture(world["shared"])
    start = captured[0].captured_at
    found, unattributed = broadcasters(captured, start, captured[-1].captured_at)
    assert {b.uas_id for b in found} == {SERIAL, SECOND}
    for b in found:
        assert all(isinstance(decode(r), BasicId) for r in b.rows)  # only the Basic IDs name their drone
        assert b.conflict == ((GENUINE_MAC, tuple(sorted([SERIAL, SECOND]))),)
    singles = [m for c in captured for m in flatten([c.message])]
    assert unattributed == sum(not isinstance(m, BasicId) for m in singles) > 0  # counted, not guessed


def test_conflicts_in_a_claims_batch(world, capsys, tmp_path):
    shared_return = tmp_path / "two-shared.h5"
    shared_return.write_bytes(world["two"].read_bytes())
    csv = tmp_path / "claims.csv"
    csv.write_text(f"file,serial,rid_capture\ntwo.h5,,{world['impostor']}\ntwo-shared.h5,{SECOND},{world['shared']}\n")
    code, out = _check(world, capsys, str(world["two"]), str(shared_return), "--claims", str(csv))
    assert code == 1 and [o["claim"]["serial"] for o in out] == [SERIAL, SECOND]
    assert all(o["decision"] != "accept" and "remote-id-conflict" in o["reasons"] for o in out)
    assert len(out[0]["remote_id"]["conflict"]) == 2  # the impostor's capture: two transmitters of one serial
    assert out[1]["remote_id"]["conflict"] == [{"transmitter": GENUINE_MAC, "serials": sorted([SERIAL, SECOND])}]


def test_import_refuses_a_conflicting_drone(world, capsys, tmp_path):
    """`authn import --rid-capture` would write the messages without their transmitters: refused."""
    import numpy as np

    from signatures.recording import read_recording

    rec = read_recording(world["two"])
    np.save(tmp_path / "iq.npy", rec.iq)
    c = rec.config
    out = tmp_path / "imported.h5"
    args = ["import", "array", str(tmp_path / "iq.npy"), "--domain", "if", "--carrier-hz", repr(c.carrier_hz),
            "--pri-s", repr(c.pri_s), "--bandwidth-hz", repr(c.bandwidth_hz), "--ramp-s", repr(c.ramp_s),
            "--sample-rate-hz", repr(c.sample_rate_hz), "--first-range-m", repr(c.range_offset_m),
            "--start-time", rec.start_time.isoformat(), "--site-lat", repr(rec.site.lat_deg),
            "--site-lon", repr(rec.site.lon_deg), "--site-alt", repr(rec.site.alt_m), "--out", str(out),
            "--rid-capture", str(world["impostor"])]
    capsys.readouterr()
    assert main(args) == 2 and not out.exists()
    err = capsys.readouterr().err
    assert "conflicting transmitters" in err and IMPOSTOR_MAC in err and GENUINE_MAC in err
