"""`authn check` end to end on simulated returns: accept path, spoofs, batch mode, JSON contract.

A single check is a track of one dwell, decided by Wald's sequential test (authn/track.py): at the
default targets (--false-accept 1e-3, --false-reject 1e-2: accept at >= 6.90 nats, refute at
<= -4.61) one unsigned dwell, capped at +-4 nats, reaches neither bound and is `inconclusive`
(exit 4) unless another forbid rejects it; its verification LLR is the least over the background
and every other model registered at the site. The demo registry holds the M300 and the M600, which
the shipped cards mark radar-confusable, so a genuine unsigned M300 is accepted only where it has
no such alternative and the targets are looser (0.02 / 0.02: +-3.89 nats), or over a track."""

from __future__ import annotations

import json
from datetime import datetime, timezone
from pathlib import Path

import pytest

from authn.cli import main
from authn.demo import register_examples
from authn.scenario import Broadcast, simulate_flight
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.recording import write_recording
from signatures.sim.scene import Scene

M600, M300 = "1581BDEM00000001", "1581BDEM00000002"
LOOSE = ("--false-accept", "0.02", "--false-reject", "0.02")  # +-3.89 nats: one dwell can decide
CONTRACT_KEYS = {"decision", "reasons", "claim", "registry", "radar", "kinematics", "skipped", "timings_ms", "audit_id"}


def _flight(out: Path, name: str, flies: str, serial: str | None, offset: float = 0.0, **scene) -> Path:
    kind = "bird" if flies == "bird" else "uav"
    sc = Scene(kind=kind, profile=shipped_profiles().get(flies), snr_db=20.0,
               **{"range_m": 400.0, "radial_speed_mps": 3.0, "elevation_deg": 10.0, **scene})
    bc = Broadcast(serial=serial, offset_along_los_m=offset) if serial else None
    rec, _ = simulate_flight(sc, get_preset("paper"), 11, bc, azimuth_deg=60.0,
                             start_time=datetime.now(timezone.utc))
    return write_recording(rec, out / f"{name}.h5")


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    root = tmp_path_factory.mktemp("e2e")
    db = f"sqlite:///{root / 'r.sqlite3'}"
    register_examples(db)
    files = {
        "genuine": _flight(root, "genuine", "m300", M300),
        "type": _flight(root, "type", "phantom4", M600),
        "position": _flight(root, "position", "m600", M600, offset=150.0),
        "bird": _flight(root, "bird", "bird", None, range_m=150.0),
    }
    return root, db, files


@pytest.fixture(scope="module")
def solo(setup) -> str:
    """A site where the M300 is the only registered model: its one alternative is the background."""
    root, _, _ = setup
    db = f"sqlite:///{root / 'solo.sqlite3'}"
    assert main(["--db", db, "register", "--serial", M300, "--model", "m300", "--valid-from", "2025-01-01"]) == 0
    return db


def _check(db: str, path: Path, capsys, *extra: str) -> tuple[int, dict]:
    capsys.readouterr()
    code = main(["--db", db, "check", str(path), "--json", *extra])
    return code, json.loads(capsys.readouterr().out)


def test_genuine_claim_is_accepted(setup, solo, capsys) -> None:
    """A genuine unsigned M300 at a site where nothing registered is confusable with it, at the
    looser targets: its one dwell (LLR against the background well above the cap) accepts."""
    _, _, files = setup
    code, out = _check(solo, files["genuine"], capsys, *LOOSE)
    assert code == 0 and out["decision"] == "accept" and out["reasons"] == ["registered-active"]
    assert "against" not in out["radar"]["verification"]  # the background its only alternative: none named
    assert out["radar"]["verification"]["llr"] >= 3.89 + 1.0  # a margin over the bound, not a lucky seed
    assert CONTRACT_KEYS <= set(out)
    assert out["claim"]["source"] == "remote_id" and out["registry"]["model"] == "m300"
    assert out["radar"]["model"] == "m300" and out["radar"]["known"] and out["radar"]["gated"]
    assert abs(out["radar"]["range_m"] - 400.0) <= 1.0
    assert out["kinematics"]["range_residual_m"] <= out["kinematics"]["range_tolerance_m"]
    assert out["skipped"] == [] and out["audit_id"] >= 1
    assert "to_decide" not in out  # only an inconclusive decision says what would decide it


def test_genuine_unsigned_dwell_beside_a_confusable_model_is_inconclusive(setup, capsys) -> None:
    """The same dwell at the demo site (the M600 registered too) and the default targets: one
    dwell never accepts on radar alone; exit 4, with what would decide it."""
    _, db, files = setup
    code, out = _check(db, files["genuine"], capsys)
    assert code == 4 and out["decision"] == "inconclusive"
    assert out["reasons"] == ["radar-confusable-unsigned", "radar-inconclusive"]
    assert CONTRACT_KEYS <= set(out) and out["audit_id"] >= 1
    td = out["to_decide"]
    assert (td["accept_nats"], td["reject_nats"], td["dwells"]) == (6.9, -4.61, 1)
    assert 0 < td["llr_nats"] < td["accept_nats"] and td["closest"] == "m600" and td["signature"] is True


def test_position_spoof_is_rejected(setup, capsys) -> None:
    """A kinematic forbid rejects on one dwell, whatever the sequential test says."""
    _, db, files = setup
    code, out = _check(db, files["position"], capsys)
    assert code == 1 and out["decision"] == "reject" and "range-mismatch" in out["reasons"]


def test_type_spoof_is_never_accepted_and_refuted_at_looser_targets(setup, capsys) -> None:
    """A Phantom 4 claiming the M600: at the defaults its one dwell (evidence against the claim,
    capped at -4 nats) is inconclusive, never an accept. At the looser targets its least LLR is past the
    refute bound, but refuting reads the alternatives together, and the registered M300, which radar
    cannot tell from an M600, explains the dwell as well as the claim: one dwell is not refuted; a track
    is (tests/decision/test_earned_accept.py)."""
    _, db, files = setup
    code, out = _check(db, files["type"], capsys)
    assert code == 4 and out["decision"] == "inconclusive" and "radar-inconclusive" in out["reasons"]
    assert out["to_decide"]["llr_nats"] < 0 and out["radar"]["verification"]["llr"] < -3.89 - 1.0
    code, out = _check(db, files["type"], capsys, *LOOSE)
    assert out["decision"] != "accept" and code in (1, 4)
    d = out["to_decide"] if out["decision"] == "inconclusive" else None
    assert d is None or d["llr_nats"] <= -3.89 < d["refute_llr_nats"] < 0


def test_bird_checked_against_a_serial(setup, solo, capsys) -> None:
    """A bird checked as the M300: the classifier alone (-3 nats) refutes no single dwell, so the
    dwell is inconclusive with the evidence against the claim; a track of bird dwells is
    rejected as not a drone."""
    root, db, files = setup
    code, out = _check(db, files["bird"], capsys, "--serial", M300)
    assert code == 4 and out["decision"] == "inconclusive" and out["radar"]["model"] == "bird"
    assert "radar-inconclusive" in out["reasons"] and out["to_decide"]["llr_nats"] < 0
    assert set(out["radar"]["verification"]["terms"]) == {"classifier"}
    assert out["kinematics"] is None and "kinematics" in out["skipped"]
    track = root / "bird-track"
    assert main(["simulate", "--model", "bird", "--range", "150", "--speed", "3", "--snr", "20", "--track", "4",
                 "--out", str(track)]) == 0
    code, out = _check(solo, track, capsys, "--track", "--serial", M300)
    assert code == 1 and out["decision"] == "reject" and "radar-not-a-drone" in out["reasons"], out["reasons"]
    assert out["llr"] <= -4.61 and out["dwells_used"] >= 2


def test_batch_mode_with_claims_csv(setup, capsys) -> None:
    root, db, files = setup
    claims = root / "claims.csv"
    claims.write_text(f"file,serial\nbird.h5,{M300}\n")
    capsys.readouterr()
    code = main(["--db", db, "check", str(root), "--claims", str(claims), "--json"])
    results = json.loads(capsys.readouterr().out)
    assert code == 1  # one rejected (the position spoof), the rest inconclusive (4 < 1), none bad
    by_file = {Path(r["file"]).stem: r for r in results}
    assert set(by_file) == set(files)
    assert {k: r["decision"] for k, r in by_file.items()} == {
        "genuine": "inconclusive", "type": "inconclusive", "position": "reject", "bird": "inconclusive"}
    assert by_file["bird"]["claim"]["serial"] == M300
    ids = [r["audit_id"] for r in results]
    assert len(set(ids)) == len(ids) == 4
    assert main(["--db", db, "audit", "verify"]) == 0


HEAVY = ("sklearn", "torch", "scipy", "matplotlib", "sqlalchemy", "alembic", "onnxruntime", "numpy.ma")


@pytest.mark.parametrize("serial,radar_modules", [(M300, True), ("1581BUNKNOWN0001", False)])
def test_cold_check_imports_only_what_it_needs(setup, serial: str, radar_modules: bool) -> None:
    """A check process never imports the heavy stacks (PERF-NOTES: they are the CLI's latency);
    a registry-only rejection does not even import the radar modules."""
    import subprocess
    import sys

    _, db, files = setup
    code = ("import sys; from authn.cli import main; code = main(sys.argv[1:]); "
            f"print('IMPORTS', code, sorted(m for m in sys.modules if m in {HEAVY!r} or m.split('.')[0] in {HEAVY!r}), "
            "'signatures.features' in sys.modules, 'signatures.classify.inference' in sys.modules)")
    proc = subprocess.run([sys.executable, "-c", code, "--db", db, "check", str(files["genuine"]), "--serial",
                           serial, "--json"], capture_output=True, text=True, timeout=120)
    line = next((x for x in proc.stdout.splitlines() if x.startswith("IMPORTS ")), proc.stdout[-300:] + proc.stderr)
    assert line == f"IMPORTS {4 if radar_modules else 1} [] {radar_modules} {radar_modules}"  # 4: inconclusive


def test_the_decision_carries_the_verification_of_the_registered_model(setup, capsys) -> None:
    """The check scores the return against the registered model's physics and the classifier,
    against the background and each other model registered (active) at the site; the least counts.
    A genuine M300 favours its claim (least against the M600), a Phantom 4 claiming the M600 does
    not, and the sequential test's LLR follows the score (capped at +-4 nats for one dwell)."""
    _, db, files = setup
    _, genuine = _check(db, files["genuine"], capsys)
    v = genuine["radar"]["verification"]
    assert v["llr"] > 0 and set(v["terms"]) == {"physics", "classifier"}
    assert set(v["against"]) == {"unknown", "m600"}  # the revoked Phantom 4 is no alternative
    assert v["against"]["unknown"] == pytest.approx(sum(v["terms"].values()), abs=1e-3)
    assert v["llr"] == min(v["against"].values()) and v["closest"] == "m600"
    assert genuine["to_decide"]["llr_nats"] == pytest.approx(min(4.0, v["llr"]), abs=0.01)
    rate = v["compared"]["flash_rate_hz"]  # what the physics compared, for the operator
    assert rate["claimed"] == pytest.approx(80.0, abs=0.01) and 0.8 <= rate["measured"] / rate["claimed"] <= 1.2
    _, spoof = _check(db, files["type"], capsys)
    sv = spoof["radar"]["verification"]
    assert sv["llr"] < 0 and sv["llr"] == min(sv["against"].values()) and set(sv["against"]) == {"unknown", "m300"}
    assert spoof["decision"] == "inconclusive" and "radar-inconclusive" in spoof["reasons"]
    assert spoof["to_decide"]["llr_nats"] == pytest.approx(max(-4.0, sv["llr"]), abs=0.01)


def test_a_model_registered_from_its_physics_is_verified_without_a_classifier(tmp_path, capsys) -> None:
    """Profiles no bundle was trained on: the classifier has no say, the physics decides. At a
    site of its own (the M300 registered beside the twin would be an alternative radar cannot tell
    from it), at the looser targets: an M300 flies for a serial registered as an airframe turning
    40 % faster (one dwell refutes it) and for one registered as an airframe with its physics (the
    physics alone, about 2.3 nats a dwell, accepts over a track, not on one dwell)."""
    db = f"sqlite:///{tmp_path / 'physics.sqlite3'}"
    m300 = shipped_profiles()["m300"].to_dict()
    twin = {**m300, "slug": "m300-twin", "name": "M300 twin"}
    fast = {**m300, "slug": "fast-quad", "name": "Fast quad", "rotor_rate_hz": 56.0}
    ids = [{"serial": serial, "model": model, "id_type": "serial", "status": "active",
            "valid_from": "2025-01-01T00:00:00+00:00"} for serial, model in (("1581BTWN00000001", "m300-twin"),
                                                                             ("1581BFST00000002", "fast-quad"))]
    doc = tmp_path / "registry.json"
    doc.write_text(json.dumps({"format": "authn-registry/1", "profiles": [twin, fast], "identities": ids}))
    assert main(["--db", db, "registry", "import", str(doc)]) == 0
    code, out = _check(db, _flight(tmp_path, "fast", "m300", "1581BFST00000002"), capsys, *LOOSE)
    assert (code, out["decision"], out["reasons"]) == (1, "reject", ["radar-claim-inconsistent"]), out
    assert set(out["radar"]["verification"]["terms"]) == {"physics"} and out["radar"]["verification"]["llr"] < -5.0
    code, out = _check(db, _flight(tmp_path, "twin", "m300", "1581BTWN00000001"), capsys, *LOOSE)
    assert (code, out["decision"]) == (4, "inconclusive") and set(out["radar"]["verification"]["terms"]) == {"physics"}
    assert 0 < out["to_decide"]["llr_nats"] < 3.89
    track = tmp_path / "twin-track"
    assert main(["simulate", "--model", "m300", "--range", "400", "--speed", "3", "--snr", "20", "--rid-serial",
                 "1581BTWN00000001", "--track", "6", "--out", str(track)]) == 0
    code, out = _check(db, track, capsys, "--track", *LOOSE)
    assert (code, out["decision"], out["reasons"]) == (0, "accept", ["registered-active"]), out
    assert all(set(d["terms"]) == {"physics"} and d["llr"] > 0 for d in out["dwells"])
