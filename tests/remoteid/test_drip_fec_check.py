"""A simulated sender with forward-error-correction pages (`authn simulate --rid-fec`), checked
end to end: `authn check` verifies it, with every page or with one lost; a signature whose
window has not begun is `not-yet-valid` and rejected with its own reason."""

from __future__ import annotations

import json
from dataclasses import replace
from datetime import datetime, timezone
from pathlib import Path

import pytest

from authn.cli import main
from remoteid import AuthPage, AuthPage0, decode
from signatures.recording import read_recording, write_recording

SERIAL = "1581BDEM00000077"


@pytest.fixture(scope="module")
def world(tmp_path_factory) -> dict:
    root = tmp_path_factory.mktemp("drip-fec")
    db = f"sqlite:///{root / 'r.sqlite3'}"
    assert main(["keys", "generate", "--out", str(root / "ua.pem"), "--json"]) == 0
    assert main(["--db", db, "register", "--serial", SERIAL, "--model", "m300", "--public-key",
                 str(root / "ua.pub.pem"), "--valid-from", "2026-01-01"]) == 0
    return {"root": root, "db": db, "key": root / "ua.pem"}


def _check(world: dict, path: Path, capsys) -> tuple[int, dict]:
    capsys.readouterr()
    code = main(["--db", world["db"], "check", str(path), "--json"])
    return code, json.loads(capsys.readouterr().out)


def _auth_rows(rec) -> list[int]:
    return [i for i, r in enumerate(rec.remote_id) if isinstance(decode(bytes(r)), (AuthPage0, AuthPage))]


@pytest.mark.parametrize("sam", ["wrapper", "manifest"])
def test_simulate_rid_fec_is_checked_and_survives_one_lost_page(world: dict, sam: str, capsys) -> None:
    out = world["root"] / f"fec-{sam}.h5"
    assert main(["simulate", "--model", "m300", "--range", "500", "--speed", "3", "--rid-serial", SERIAL,
                 "--sign-key", str(world["key"]), "--sam", sam, "--rid-fec", "--out", str(out)]) == 0
    rec = read_recording(out)
    auth = _auth_rows(rec)
    page0 = decode(bytes(rec.remote_id[auth[0]]))
    assert len(auth) == page0.last_page_index + 1  # the FEC page is counted by the last page index ...
    assert page0.length <= 17 + 23 * (page0.last_page_index - 1)  # ... and not by the length
    code, doc = _check(world, out, capsys)
    assert code == 0 and doc["decision"] == "accept", doc["reasons"]
    assert doc["remote_id_auth"]["status"] == "valid" and doc["remote_id_auth"]["sam_types"] == [sam]
    for lost in (auth[0], auth[len(auth) // 2], auth[-1]):  # page 0, a middle page, the FEC page
        keep = [i for i in range(len(rec.remote_id)) if i != lost]
        path = write_recording(replace(rec, remote_id=rec.remote_id[keep], remote_id_time_s=rec.remote_id_time_s[keep]),
                               world["root"] / f"fec-{sam}-lost-{lost}.h5")
        code, doc = _check(world, path, capsys)
        assert code == 0 and doc["remote_id_auth"]["status"] == "valid", (lost, doc["remote_id_auth"])
    # a flipped bit with every page there: the parity says so
    bad = rec.remote_id.copy()
    bad[auth[1], 7] ^= 1
    path = write_recording(replace(rec, remote_id=bad), world["root"] / f"fec-{sam}-flipped.h5")
    code, doc = _check(world, path, capsys)
    assert code == 1 and "remote-id-auth-invalid" in doc["reasons"]
    assert "FEC parity error" in doc["remote_id_auth"]["reason"]


def test_rid_fec_needs_a_key(world: dict, capsys) -> None:
    assert main(["simulate", "--model", "m300", "--range", "500", "--rid-serial", SERIAL, "--rid-fec",
                 "--out", str(world["root"] / "nokey.h5")]) == 2
    assert "--rid-fec need --sign-key" in capsys.readouterr().err


def test_a_signature_not_yet_valid_is_rejected_with_its_own_reason(world: dict, capsys) -> None:
    from authn.scenario import Broadcast, Signing, simulate_flight
    from authn.uakeys import load
    from signatures.profiles import shipped_profiles
    from signatures.radar import get_preset
    from signatures.sim.scene import Scene

    key = load(world["key"])
    scene = Scene(profile=shipped_profiles()["m300"], range_m=500.0, radial_speed_mps=3.0, snr_db=20.0)
    now = datetime.now(timezone.utc)
    for offset, status in ((86400.0, "not-yet-valid"), (-86400.0, "expired")):
        signing = Signing(key.private_raw, key.det, signed_at_offset_s=offset, fec=True)
        rec, _ = simulate_flight(scene, get_preset("paper"), 5, Broadcast(serial=SERIAL, signing=signing),
                                 start_time=now)
        path = write_recording(rec, world["root"] / f"{status}.h5")
        code, doc = _check(world, path, capsys)
        auth = doc["remote_id_auth"]
        assert code == 1 and f"remote-id-auth-{status}" in doc["reasons"], doc["reasons"]
        assert "remote-id-auth-invalid" not in doc["reasons"]
        assert auth["status"] == status and auth["reason"].startswith(f"verified-but-{status}: DRIP wrapper")
        assert auth["det"] == key.det.hex() and auth["covered_messages"] == []
