"""Signed Remote ID (IETF DRIP, RFC 9575) end to end through the real CLI: keys generate ->
register -> simulate --sign-key -> check; every spoof rejected with its own reason.

A single check is a track of one dwell, decided by Wald's sequential test: at the default targets
one unsigned dwell (capped at +-4 nats) reaches neither bound and is `inconclusive` (exit 4); with a
valid signature the radar need only favour the claim (LLR > 0) to accept. Every identity here is an
M300 (no radar-confusable model registered), so at the looser targets (--false-accept 0.02
--false-reject 0.02: +-3.89 nats) one unsigned genuine dwell accepts on radar alone."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from authn.cli import main
from signatures.recording import read_recording, write_recording

GENUINE, VICTIM = "1581BDEM00000099", "1581BDEM00000098"
LOOSE = ("--false-accept", "0.02", "--false-reject", "0.02")


@pytest.fixture(scope="module")
def world(tmp_path_factory) -> dict:
    root = tmp_path_factory.mktemp("drip")
    db = f"sqlite:///{root / 'r.sqlite3'}"
    keys = {}
    for who in ("ua", "victim", "attacker"):
        assert main(["keys", "generate", "--out", str(root / f"{who}.pem"), "--json"]) == 0
        keys[who] = root / f"{who}.pem"
    for serial, who in ((GENUINE, "ua"), (VICTIM, "victim")):
        assert main(["--db", db, "register", "--serial", serial, "--model", "m300", "--public-key",
                     str(root / f"{who}.pub.pem"), "--valid-from", "2026-01-01"]) == 0
    assert main(["--db", db, "register", "--serial", "1581BDEM00000097", "--model", "m300",
                 "--valid-from", "2026-01-01"]) == 0  # no key: signatures are optional for it
    return {"root": root, "db": db, "keys": keys}


def _fly(world: dict, name: str, serial: str, *sign: str) -> Path:
    out = world["root"] / f"{name}.h5"
    assert main(["simulate", "--model", "m300", "--range", "500", "--speed", "3", "--snr", "20",
                 "--rid-serial", serial, "--out", str(out), *sign]) == 0
    return out


def _check(world: dict, path: Path, capsys, *extra: str) -> tuple[int, dict]:
    capsys.readouterr()
    code = main(["--db", world["db"], "check", str(path), "--json", *extra])
    return code, json.loads(capsys.readouterr().out)


@pytest.mark.parametrize("sam", ["wrapper", "manifest", "frame"])
def test_genuine_signed_flight_is_accepted(world: dict, sam: str, capsys) -> None:
    path = _fly(world, f"genuine-{sam}", GENUINE, "--sign-key", str(world["keys"]["ua"]), "--sam", sam)
    code, out = _check(world, path, capsys)
    assert (code, out["decision"], out["reasons"]) == (0, "accept", ["registered-active"])
    auth = out["remote_id_auth"]
    assert auth["status"] == "valid" and auth["sam_types"] == [sam]
    assert auth["covered_messages"], "the signature covers the Basic ID and Location messages"
    assert out["registry"]["has_key"] is True and out["kinematics"] is not None


SPOOFS = {
    # (signing options given the keys, expected status, the reasons that must be there)
    "same-type impersonation, unsigned": (lambda k: [], "absent", {"remote-id-auth-required"}),
    "signed with the impersonator's own key": (lambda k: ["--sign-key", str(k["attacker"])], "unknown-key",
                                              {"remote-id-auth-required"}),
    "forged: the victim's DET, another key": (lambda k: ["--sign-key", str(k["attacker"]), "--sign-det", "VICTIM"],
                                              "invalid", {"remote-id-auth-invalid"}),
    "replayed: signed a day before the dwell": (lambda k: ["--sign-key", str(k["victim"]), "--sign-age", "86400"],
                                                "expired", {"remote-id-auth-expired"}),
    "Location tampered after signing (wrapper)": (lambda k: ["--sign-key", str(k["victim"]),
                                                             "--tamper-after-signing"],
                                                  "invalid", {"remote-id-auth-invalid"}),
    "Location tampered after signing (manifest)": (lambda k: ["--sign-key", str(k["victim"]), "--sam", "manifest",
                                                              "--tamper-after-signing"],
                                                   "valid", {"remote-id-implausible"}),
}


def _victim_det(world: dict, capsys) -> str:
    from authn.uakeys import load

    return load(world["keys"]["victim"]).det.hex()


@pytest.mark.parametrize("name", list(SPOOFS))
def test_spoofs_of_a_keyed_identity_are_rejected(world: dict, name: str, capsys) -> None:
    options, status, reasons = SPOOFS[name]
    sign = [_victim_det(world, capsys) if o == "VICTIM" else o for o in options(world["keys"])]
    path = _fly(world, name.replace(" ", "-").replace(":", "").replace(",", ""), VICTIM, *sign)
    code, out = _check(world, path, capsys)
    assert code == 1 and out["decision"] == "reject", out["reasons"]
    assert reasons <= set(out["reasons"]), out["reasons"]
    assert out["remote_id_auth"]["status"] == status
    if status == "valid":  # the manifest does not cover the moved Location: not used, and flagged
        assert "unsigned-location" in out["remote_id"]["issues"]
        assert 1 not in out["remote_id_auth"]["covered_messages"]


def test_drip_session_id_identity(world: dict, capsys, tmp_path: Path) -> None:
    """A DRIP identity: UAS ID type 4, the session ID (type 01 + the DET) as registry key."""
    key = tmp_path / "det.pem"
    capsys.readouterr()
    assert main(["keys", "generate", "--out", str(key), "--json"]) == 0
    session = json.loads(capsys.readouterr().out)["session_id"]
    assert main(["--db", world["db"], "register", "--serial", session, "--id-type", "specific_session",
                 "--model", "m300", "--public-key", str(tmp_path / "det.pub.pem"), "--valid-from", "2026-01-01"]) == 0
    path = _fly(world, "det-identity", session, "--sign-key", str(key))
    code, out = _check(world, path, capsys)
    assert code == 0 and out["claim"]["serial"] == session and out["remote_id_auth"]["status"] == "valid"


def test_identity_without_a_key_accepts_signed_and_unsigned(world: dict, capsys) -> None:
    """No key registered: no signature is required, and one by an unknown key neither counts nor
    rejects. The radar alone decides: at the defaults one dwell is inconclusive, at the looser
    targets it accepts (the LLR well past the bound)."""
    for name, sign in (("nokey-unsigned", []), ("nokey-signed", ["--sign-key", str(world["keys"]["ua"])])):
        path = _fly(world, name, "1581BDEM00000097", *sign)
        code, out = _check(world, path, capsys)
        assert (code, out["reasons"]) == (4, ["radar-inconclusive"]), out["reasons"]
        code, out = _check(world, path, capsys, *LOOSE)
        assert (code, out["reasons"]) == (0, ["registered-active"]), out["reasons"]
        assert out["radar"]["verification"]["llr"] > 3.89 + 1.0
        assert out["remote_id_auth"]["status"] == ("absent" if not sign else "unknown-key")


def _with_pages(src: Path, dst: Path, pages: list[bytes]) -> Path:
    rec = read_recording(src)
    from dataclasses import replace

    rows = np.concatenate([rec.remote_id, np.frombuffer(b"".join(pages), np.uint8).reshape(-1, 25)])
    times = np.concatenate([rec.remote_id_time_s, np.full(len(pages), rec.remote_id_time_s[-1])])
    return write_recording(replace(rec, remote_id=rows, remote_id_time_s=times), dst)


@pytest.mark.parametrize("damage", ["impossible length", "missing page"])
def test_malformed_authentication_pages_are_invalid(world: dict, damage: str, capsys) -> None:
    from datetime import datetime, timezone

    from remoteid.drip import paginate

    base = _fly(world, "unsigned-base", GENUINE)
    pages = paginate(bytes(range(1, 60)), datetime.now(timezone.utc))  # 59 bytes: pages 0..2
    if damage == "impossible length":
        page0 = bytearray(pages[0])
        page0[3] = 200  # 200 bytes cannot fit in pages 0..2
        pages = [bytes(page0), *pages[1:]]
    else:
        pages = [pages[0], pages[2]]
    code, out = _check(world, _with_pages(base, world["root"] / f"pages-{damage[:4]}.h5", pages), capsys)
    assert code == 1 and "remote-id-auth-invalid" in out["reasons"]
    assert out["remote_id_auth"]["status"] == "invalid" and out["remote_id_auth"]["reason"]


def test_the_audit_keeps_the_authentication(world: dict, capsys) -> None:
    path = _fly(world, "audited", GENUINE, "--sign-key", str(world["keys"]["ua"]))
    code, out = _check(world, path, capsys)
    capsys.readouterr()
    assert main(["--db", world["db"], "audit", "show", str(out["audit_id"])]) == 0
    payload = json.loads(capsys.readouterr().out)["payload"]
    assert payload["remote_id_auth"]["status"] == "valid"
    assert payload["policy_input"]["context"]["remote_id_auth"] == "valid"
    assert payload["policy_input"]["principal"]["has_key"] is True
    assert main(["--db", world["db"], "audit", "replay", str(out["audit_id"])]) == 0


def test_rid_decode_shows_and_verifies_authentication_pages(world: dict, capsys) -> None:
    path = _fly(world, "decode-me", GENUINE, "--sign-key", str(world["keys"]["ua"]), "--sign-age", "0")
    rows = [bytes(r).hex() for r in read_recording(path).remote_id]
    capsys.readouterr()
    assert main(["rid", "decode", *rows]) == 0
    out = capsys.readouterr().out
    assert "DRIP wrapper" in out and "DET 2001:3" in out and "verification" not in out
    for key, status in (("ua", "valid"), ("attacker", "unknown-key")):
        assert main(["rid", "decode", *rows, "--public-key", str(world["root"] / f"{key}.pub.pem"), "--json"]) == 0
        text = capsys.readouterr().out
        doc = json.loads(text[text.rindex('{\n  "authentication"'):])
        assert doc["verification"]["status"] == status


def test_a_link_from_a_trusted_registry_delivers_the_key(world: dict, tmp_path: Path, capsys) -> None:
    """A DRIP identity registered without a key: the drone broadcasts its registry's Link (the
    HDA's signature over its DET and key) beside its own signature; a site that trusts that
    registry verifies it (a valid signature: the radar need only favour the claim, accepted), one
    that does not sees an unknown key (the radar alone: one dwell is inconclusive)."""
    from datetime import datetime, timedelta, timezone

    from authn.scenario import Broadcast, Signing, simulate_flight
    from authn.uakeys import generate
    from remoteid.drip import encode_link
    from signatures.profiles import shipped_profiles
    from signatures.radar import get_preset
    from signatures.sim.scene import Scene

    hda, ua = generate(hda=2), generate()
    now = datetime.now(timezone.utc)
    day = timedelta(days=1)
    link = encode_link(ua.det, ua.public_raw, hda.det, hda.private_raw, now - day, now + day)
    assert main(["--db", world["db"], "register", "--serial", ua.session_id, "--id-type", "specific_session",
                 "--model", "m300", "--valid-from", "2026-01-01"]) == 0
    scene = Scene(profile=shipped_profiles()["m300"], range_m=500.0, radial_speed_mps=3.0, snr_db=20.0)
    rec, _ = simulate_flight(scene, get_preset("paper"), 3, Broadcast(serial=ua.session_id, id_type=4, signing=Signing(
        ua.private_raw, ua.det, link=link)), start_time=now)
    path = write_recording(rec, tmp_path / "linked.h5")
    trust = tmp_path / "trust.json"
    trust.write_text(json.dumps({"registries": [{"det": hda.det.hex(), "public_key": hda.public_raw.hex()}]}))
    for extra, status, code in (([], "unknown-key", 4), (["--trust-registry", str(trust)], "valid", 0)):
        capsys.readouterr()
        assert main(["--db", world["db"], "check", str(path), "--json", *extra]) == code
        out = json.loads(capsys.readouterr().out)
        assert out["remote_id_auth"]["status"] == status, out["remote_id_auth"]
    assert out["remote_id_auth"]["sam_types"] == ["link", "wrapper"]


def test_a_valid_signature_by_someone_else_does_not_count(world: dict, tmp_path: Path, capsys) -> None:
    """An impersonator with a genuine Link from a trusted registry signs correctly with its own
    key, while claiming a serial that is not its own: the signature verifies but is not the
    claimed identity's, so it counts as an unknown key: no accept on it (the radar alone leaves one
    dwell inconclusive, where a valid signature would accept), and a keyed victim then rejects."""
    from datetime import datetime, timedelta, timezone

    from authn.scenario import Broadcast, Signing, simulate_flight
    from authn.uakeys import generate
    from remoteid.drip import encode_link
    from signatures.profiles import shipped_profiles
    from signatures.radar import get_preset
    from signatures.sim.scene import Scene

    hda, attacker = generate(hda=3), generate()
    now = datetime.now(timezone.utc)
    link = encode_link(attacker.det, attacker.public_raw, hda.det, hda.private_raw, now - timedelta(days=1),
                       now + timedelta(days=1))
    trust = tmp_path / "trust.json"
    trust.write_text(json.dumps({"registries": [{"det": hda.det.hex(), "public_key": hda.public_raw.hex()}]}))
    scene = Scene(profile=shipped_profiles()["m300"], range_m=500.0, radial_speed_mps=3.0, snr_db=20.0)
    for serial, code in (("1581BDEM00000097", 4), (VICTIM, 1)):
        rec, _ = simulate_flight(scene, get_preset("paper"), 4, Broadcast(serial=serial, signing=Signing(
            attacker.private_raw, attacker.det, link=link)), start_time=now)
        path = write_recording(rec, tmp_path / f"claims-{serial}.h5")
        capsys.readouterr()
        assert main(["--db", world["db"], "check", str(path), "--json", "--trust-registry", str(trust)]) == code
        out = json.loads(capsys.readouterr().out)
        assert out["remote_id_auth"]["status"] == "unknown-key" and "not the claimed" in out["remote_id_auth"]["reason"]
        assert out["decision"] != "accept"


def test_human_output_shows_the_remote_id_authentication(world: dict, capsys) -> None:
    """`authn check signed.h5` without --json names what the signature came to; a batch piped
    is one tab-separated line per return, identifiers whole. (The unsigned dwell is one dwell of
    radar alone at the default targets: inconclusive, exit 4, the batch's worst here.)"""
    signed = _fly(world, "human-signed", GENUINE, "--sign-key", str(world["keys"]["ua"]))
    unsigned = _fly(world, "human-unsigned", "1581BDEM00000097")
    capsys.readouterr()
    assert main(["--db", world["db"], "check", str(signed)]) == 0
    out = capsys.readouterr().out
    assert "remote id auth" in out and "valid (wrapper), covers" in out, out
    assert main(["--db", world["db"], "check", str(unsigned)]) == 4
    assert "remote id auth" not in capsys.readouterr().out  # nothing signed, nothing to say
    assert main(["--db", world["db"], "check", str(signed), str(unsigned)]) == 4
    rows = [line.split("\t") for line in capsys.readouterr().out.splitlines()]
    assert [r[:3] for r in rows] == [["human-signed.h5", GENUINE, "accept"],
                                     ["human-unsigned.h5", "1581BDEM00000097", "inconclusive"]]
