"""`authn check` end to end on simulated returns: accept path, spoofs, batch mode, JSON contract."""

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
from signatures.scene import Scene

M600, M300 = "1581BDEM00000001", "1581BDEM00000002"
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


def _check(db: str, path: Path, capsys, *extra: str) -> tuple[int, dict]:
    capsys.readouterr()
    code = main(["--db", db, "check", str(path), "--json", *extra])
    return code, json.loads(capsys.readouterr().out)


def test_genuine_claim_is_accepted(setup, capsys) -> None:
    _, db, files = setup
    code, out = _check(db, files["genuine"], capsys)
    assert code == 0 and out["decision"] == "accept" and out["reasons"] == ["registered-active"]
    assert CONTRACT_KEYS <= set(out)
    assert out["claim"]["source"] == "remote_id" and out["registry"]["model"] == "m300"
    assert out["radar"]["model"] == "m300" and out["radar"]["known"] and out["radar"]["gated"]
    assert abs(out["radar"]["range_m"] - 400.0) <= 1.0
    assert out["kinematics"]["range_residual_m"] <= out["kinematics"]["range_tolerance_m"]
    assert out["skipped"] == [] and out["audit_id"] >= 1


@pytest.mark.parametrize("case,reason", [("type", "radar-claim-inconsistent"), ("position", "range-mismatch")])
def test_spoofs_are_rejected(setup, capsys, case: str, reason: str) -> None:
    _, db, files = setup
    code, out = _check(db, files[case], capsys)
    assert code == 1 and out["decision"] == "reject" and reason in out["reasons"]


def test_bird_checked_against_a_serial(setup, capsys) -> None:
    _, db, files = setup
    code, out = _check(db, files["bird"], capsys, "--serial", M300)
    assert code == 1 and out["radar"]["model"] == "bird" and out["reasons"] == ["radar-not-a-drone"]
    assert out["kinematics"] is None and "kinematics" in out["skipped"]


def test_batch_mode_with_claims_csv(setup, capsys) -> None:
    root, db, files = setup
    claims = root / "claims.csv"
    claims.write_text(f"file,serial\nbird.h5,{M300}\n")
    capsys.readouterr()
    code = main(["--db", db, "check", str(root), "--claims", str(claims), "--json"])
    results = json.loads(capsys.readouterr().out)
    assert code == 1  # some rejected, none bad
    by_file = {Path(r["file"]).stem: r for r in results}
    assert set(by_file) == set(files)
    assert by_file["genuine"]["decision"] == "accept" and by_file["bird"]["claim"]["serial"] == M300
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
            "'signatures.features' in sys.modules, 'signatures.inference' in sys.modules)")
    proc = subprocess.run([sys.executable, "-c", code, "--db", db, "check", str(files["genuine"]), "--serial",
                           serial, "--json"], capture_output=True, text=True, timeout=120)
    line = next((x for x in proc.stdout.splitlines() if x.startswith("IMPORTS ")), proc.stdout[-300:] + proc.stderr)
    assert line == f"IMPORTS {0 if radar_modules else 1} [] {radar_modules} {radar_modules}"


def test_the_decision_carries_the_verification_of_the_registered_model(setup, capsys) -> None:
    """The check scores the return against the registered model's physics and the classifier:
    a genuine M300 favours its claim, a Phantom 4 claiming the M600 does not, and the policy's
    reason follows the score."""
    _, db, files = setup
    _, genuine = _check(db, files["genuine"], capsys)
    v = genuine["radar"]["verification"]
    assert v["llr"] > 0 and set(v["terms"]) == {"physics", "classifier"}
    assert v["llr"] == pytest.approx(sum(v["terms"].values()), abs=1e-3)
    rate = v["compared"]["flash_rate_hz"]  # what the physics compared, for the operator
    assert rate["claimed"] == pytest.approx(80.0, abs=0.01) and 0.8 <= rate["measured"] / rate["claimed"] <= 1.2
    _, spoof = _check(db, files["type"], capsys)
    assert spoof["radar"]["verification"]["llr"] < 0 and spoof["reasons"] == ["radar-claim-inconsistent"]


def test_a_model_registered_from_its_physics_is_verified_without_a_classifier(setup, tmp_path, capsys) -> None:
    """Profiles no bundle was trained on: the classifier has no say, the physics decides. An
    M300 flies for a serial registered as an airframe with its physics (accepted) and for one
    registered as an airframe turning 40 % faster (rejected)."""
    root, db, _ = setup
    m300 = shipped_profiles()["m300"].to_dict()
    twin = {**m300, "slug": "m300-twin", "name": "M300 twin"}
    fast = {**m300, "slug": "fast-quad", "name": "Fast quad", "rotor_rate_hz": 56.0}
    ids = [{"serial": serial, "model": model, "id_type": "serial", "status": "active",
            "valid_from": "2025-01-01T00:00:00+00:00"} for serial, model in (("1581BTWN00000001", "m300-twin"),
                                                                             ("1581BFST00000002", "fast-quad"))]
    doc = tmp_path / "registry.json"
    doc.write_text(json.dumps({"format": "authn-registry/1", "profiles": [twin, fast], "identities": ids}))
    assert main(["--db", db, "registry", "import", str(doc)]) == 0
    for serial, decision in (("1581BTWN00000001", "accept"), ("1581BFST00000002", "reject")):
        code, out = _check(db, _flight(tmp_path, serial, "m300", serial), capsys)
        assert out["decision"] == decision, out
        assert set(out["radar"]["verification"]["terms"]) == {"physics"}
