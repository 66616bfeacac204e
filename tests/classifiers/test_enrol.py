"""Site enrolment (issue 32): `authn models enrol DIR --labels DIR/labels.csv`, then `authn register`,
then `authn check FILE` decides with the site bundle; the card; radar-confusable pairs and their
policy; `models use` / `list`; bad input is exit 2 and one line and changes nothing; an interrupted
enrolment leaves the previous bundle active.

Small on purpose: 5 held-out recordings per shipped airframe and a 120-return simulated base set.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import replace
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pytest

from authn.cli import main
from authn.policy import PolicyEngine
from signatures.train.separability import calibration_pays
from tests.decision.test_policy import ACTIVE, GOOD, SITE, sprt_record
from tests.classifiers.conftest import own_models

N_PER_MODEL = 5
BASE = ["--base-samples", "120"]
SERIALS = {"m600": "1581BBENCH00600A", "m300": "1581BBENCH00300A", "phantom4": "1581BBENCH00004A"}


def _make_site(folder: Path, n: int, seed: int = 11) -> None:
    """n held-out recordings per shipped airframe (mixed SNR, Remote ID of its bench serial), labels.csv."""
    from authn.scenario import Broadcast
    from lab.bench.decisions import CLAIM_SCENES
    from lab.bench.worlds import render_claim
    from signatures.profiles import shipped_profiles
    from signatures.radar import get_preset
    from signatures.recording import write_recording
    from signatures.sim.sampling import sample_scene

    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    rows = ["file,model"]
    now = datetime.now(timezone.utc)
    for slug, prof in shipped_profiles().items():
        for i in range(n):
            scene = sample_scene(rng, prof, replace(CLAIM_SCENES, snr_db=(10.0, 20.0)))
            rec = render_claim("heldout", scene, get_preset("paper"), int(rng.integers(2**31)),
                               Broadcast(serial=SERIALS[slug]), float(rng.uniform(0, 360)), now)
            write_recording(rec, folder / f"{slug}-{i:02d}.h5")
            rows.append(f"{slug}-{i:02d}.h5,{slug}")
    (folder / "labels.csv").write_text("\n".join(rows) + "\n")


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict]:
    """A clean data folder (registry, models) and a site's recordings; the first enrolment."""
    root = tmp_path_factory.mktemp("enrol")
    with own_models(root) as mp:
        mp.setenv("AUTHN_DATABASE_URL", f"sqlite:///{root / 'r.sqlite3'}")
        _make_site(root / "flights", N_PER_MODEL)
        yield {"root": root, "flights": root / "flights", "models": root / "models"}


def _one_line_error(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err and len(err.splitlines()) == 1, err
    return err


def _active() -> dict:
    from signatures.classify.inference import active_map

    return active_map()


def test_enrol_register_check_uses_the_site_bundle(site: dict, capsys) -> None:
    flights = site["flights"]
    assert main(["models", "enrol", str(flights), "--labels", str(flights / "labels.csv"), "--name", "site-a",
                 "--json", *BASE]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["counts"] == {"m300": 5, "m600": 5, "phantom4": 5} and doc["sources"] == 15
    folder = site["models"] / "site-a"
    card = json.loads((folder / "card.json").read_text())
    e = card["enrolment"]
    assert e["confusion"]["rows"] == ["m300", "m600", "phantom4"]
    assert sum(map(sum, e["confusion"]["matrix"])) == sum(e["detected"].values())
    assert [p["models"] for p in e["pairwise"]] == [["m300", "m600"], ["m300", "phantom4"], ["m600", "phantom4"]]
    for p in e["pairwise"]:  # the track-level errors beside the single-dwell ones
        t = p["tracks"]
        assert t["claims"] > 0 and 0.0 <= t["false_accept_rate"] <= 1.0 and t["dwells"] == N_PER_MODEL
    assert e["tracks"]["dwells"] == 8 and e["tracks"]["sprt"]["accept_nats"] > 0
    assert e["bands"] is None  # today's physics bands unless --site-bands
    cal = e["calibration"]  # the score calibration: always fitted on the out-of-fold terms and reported
    assert cal["features"] == ["physics", "physics_above_knee", "classifier"]
    assert all(c >= 0 for c in cal["coef"]) and cal["fitted_on"] == {"genuine": 15, "type_spoof": 30}
    assert set(cal["evidence_per_genuine_dwell"]) >= {"calibrated", "uncalibrated"}
    # applied unasked only where the site's cross-validated claims say it pays, and the card says which
    assert cal["choice"]["by"] == "auto" and cal["applied"] is calibration_pays(cal["choice"])
    assert {cal["choice"][k]["level"] for k in ("calibrated", "uncalibrated")} == {"tracks"}
    assert e["method"]["score_calibration"].startswith("none") is not cal["applied"]
    assert set(e["tracks"]["genuine_accept"]) == {"m300", "m600", "phantom4"}
    # 5 recordings per model give each pair about 10 claims, too few to show it separable: every pair
    # is radar-confusable, over single dwells and over tracks (whose 5 dwells are short of 8 anyway)
    assert e["min_separable_claims"] == 29 and all(p["single_dwell"]["claims"] < 29 for p in e["pairwise"])
    assert e["confusable_pairs"] == e["confusable_pairs_tracks"] == [p["models"] for p in e["pairwise"]]
    assert e["threshold"]["applied"] == 0.0 and e["threshold"]["false_accept_target"] == 0.01
    assert {s["file"] for s in e["sources"]} == {str(p) for p in flights.glob("*.h5")}
    assert all(len(s["sha256"]) == 64 for s in e["sources"])
    assert set(card["files"]) >= {"rf.npz", "openset.npz", "site.npz"}
    assert list(_active().values()) == ["site-a"]

    assert main(["register", "--serial", SERIALS["phantom4"], "--model", "phantom4",
                 "--valid-from", "2025-01-01T00:00:00Z"]) == 0
    capsys.readouterr()
    main(["check", str(flights / "phantom4-00.h5"), "--json"])
    out = json.loads(capsys.readouterr().out)
    from signatures.classify.modelcard import read_card

    assert out["model_card_sha256"] == read_card(folder)[1]  # decided with the site bundle
    assert out["reasons"] != ["unregistered"]


def test_models_list_and_use_switch_the_active_bundle(site: dict, capsys) -> None:
    assert main(["models", "list", "--json"]) == 0
    docs = {d["name"]: d for d in json.loads(capsys.readouterr().out)}
    assert docs["site-a"]["kind"] == "site" and docs["site-a"]["active"]
    assert not docs["paper"]["active"] and docs["wide"]["active"]
    assert main(["models", "use", "shipped"]) == 0 and _active() == {}
    assert main(["models", "list", "--json"]) == 0
    docs = {d["name"]: d for d in json.loads(capsys.readouterr().out.split("\n", 1)[1])}
    assert docs["paper"]["active"] and not docs["site-a"]["active"]
    assert main(["models", "use", "site-a"]) == 0 and list(_active().values()) == ["site-a"]
    capsys.readouterr()
    assert main(["models", "use", "nonesuch"]) == 2
    assert "no site bundle named 'nonesuch'" in _one_line_error(capsys)


def test_confusable_pair_needs_a_signature(site: dict, capsys, monkeypatch) -> None:
    """A pair the card calls confusable, both registered: an unsigned claim is rejected with
    radar-confusable-unsigned; with only one of the pair registered, the rule stays silent."""
    from authn.check import Checker, _flag
    from signatures.classify.inference import load_classifier

    clf = load_classifier(path=site["models"] / "site-a")  # the instance the check will use
    monkeypatch.setattr(clf, "confusable_pairs", (("m300", "m600"),))
    for slug in ("m300", "m600"):
        main(["register", "--serial", SERIALS[slug], "--model", slug, "--valid-from", "2025-01-01T00:00:00Z"])
    checker = Checker()
    assert _flag(checker._confusable_models(clf, "m300")) is True
    assert _flag(checker._confusable_models(clf, "phantom4")) is False
    out = checker.evaluate(site["flights"] / "m300-00.h5")
    assert "radar-confusable-unsigned" in out.reasons
    assert out.evidence.policy_input()["context"]["radar_confusable"] is True
    main(["registry", "revoke", SERIALS["m600"], "--reason", "test"])
    assert _flag(checker._confusable_models(clf, "m300")) is False


def _signed_m300(key, serial: str, dwells: int, seed: int = 5) -> list:
    """Held-out dwells of an M300 whose Remote ID `serial` is signed with `key` (DRIP)."""
    from authn.scenario import Broadcast, Signing
    from lab.bench.decisions import CLAIM_SCENES
    from lab.bench.track import track_recordings
    from signatures.profiles import shipped_profiles
    from signatures.sim.sampling import sample_scene

    scene = sample_scene(np.random.default_rng(seed), shipped_profiles()["m300"], replace(CLAIM_SCENES, snr_db=20.0))
    bc = Broadcast(serial=serial, signing=Signing(private_key=key.private_raw, det=key.det))
    return track_recordings(scene, "paper", list(range(1, dwells + 1)), serial, world="heldout", broadcast=bc)


@pytest.mark.parametrize("track_pairs", [(), (("m300", "m600"),)])
def test_a_signed_claim_of_a_confusable_model_is_verified_as_the_group(site: dict, tmp_path: Path, monkeypatch,
                                                                      capsys, track_pairs: tuple) -> None:
    """Where the card says radar cannot tell the registered M300 from a registered M600 and the
    claim's DRIP signature is valid, radar verifies "an M300 or an M600" (the signature vouches for
    which); an unsigned claim is verified against the M300 alone (and rejected for the signature it
    lacks). A track asks the card's track-level pairs."""
    from authn import uakeys
    from authn.check import CheckInput, Checker
    from authn.track import Dwell, decide_track
    from signatures.classify.inference import load_classifier

    main(["models", "use", "site-a"])
    clf = load_classifier(path=site["models"] / "site-a")
    monkeypatch.setattr(clf, "confusable_pairs", (("m300", "m600"),))
    monkeypatch.setattr(clf, "confusable_track_pairs", track_pairs)
    key = uakeys.generate()
    pub = tmp_path / "ua.pub"
    pub.write_bytes(key.public_raw)
    tag = "H" if track_pairs else "G"  # one registry for the module: serials of their own
    keyed = f"1581BBENCH00300{tag}"
    assert main(["register", "--serial", keyed, "--model", "m300", "--public-key", str(pub),
                 "--valid-from", "2025-01-01T00:00:00Z"]) == 0
    assert main(["register", "--serial", f"1581BBENCH00600{tag}", "--model", "m600",
                 "--valid-from", "2025-01-01T00:00:00Z"]) == 0
    capsys.readouterr()
    checker = Checker()
    recs = _signed_m300(key, keyed, 3)
    one = checker.decide_one(CheckInput.recording(recs[0], None))
    assert one.evidence.auth.status == "valid"
    v = one.evidence.radar.verification
    assert v.verified_as == ("m300", "m600") and v.to_json()["verified_as"] == ["m300", "m600"]
    assert "radar-confusable-unsigned" not in one.reasons
    unsigned = checker.evaluate(site["flights"] / "m300-00.h5")
    assert unsigned.evidence.radar.verification.verified_as == ()
    assert "radar-confusable-unsigned" in unsigned.reasons
    out = decide_track(checker, [Dwell.recording(r, f"d{i}") for i, r in enumerate(recs)])
    assert out.evidence.radar.verification.verified_as == (("m300", "m600") if track_pairs else ())


@pytest.mark.parametrize("track_pairs", [(), (("m300", "m600"),)])
def test_a_track_check_uses_the_track_figure(site: dict, capsys, monkeypatch, track_pairs: tuple) -> None:
    """A pair confusable over single dwells: a single-dwell check rejects the unsigned claim; a
    track check asks the card's track-level pairs, so a pair separable over tracks is not
    radar-confusable there (and one confusable over tracks still is)."""
    from authn.check import Checker, _flag
    from authn.track import Dwell, decide_track
    from lab.bench.decisions import CLAIM_SCENES
    from lab.bench.track import track_recordings
    from signatures.classify.inference import load_classifier
    from signatures.profiles import shipped_profiles
    from signatures.sim.sampling import sample_scene

    main(["models", "use", "site-a"])
    clf = load_classifier(path=site["models"] / "site-a")
    monkeypatch.setattr(clf, "confusable_pairs", (("m300", "m600"),))
    monkeypatch.setattr(clf, "confusable_track_pairs", track_pairs)
    for serial, slug in ((SERIALS["m300"], "m300"), ("1581BBENCH00600T", "m600")):  # both registered and active
        main(["register", "--serial", serial, "--model", slug, "--valid-from", "2025-01-01T00:00:00Z"])
    checker = Checker()
    assert _flag(checker._confusable_models(clf, "m300")) is True
    assert _flag(checker._confusable_models(clf, "m300", tracks=True)) is bool(track_pairs)
    scene = sample_scene(np.random.default_rng(5), shipped_profiles()["m300"], replace(CLAIM_SCENES, snr_db=20.0))
    recs = track_recordings(scene, "paper", [1, 2, 3], SERIALS["m300"], world="heldout")
    out = decide_track(checker, [Dwell.recording(r, f"d{i}") for i, r in enumerate(recs)])
    assert out.policy_input["context"]["radar_confusable"] is bool(track_pairs)
    assert ("radar-confusable-unsigned" in out.reasons) is bool(track_pairs)
    single = checker.evaluate(site["flights"] / "m300-00.h5")
    assert "radar-confusable-unsigned" in single.reasons  # the single-dwell check keeps the single-dwell figure


def test_too_few_claims_never_show_a_pair_separable() -> None:
    """A pair the cross-validation saw no false accept in is separable only with enough claims to
    bound its rate (under 10 % at 95 %: 29); with fewer it is radar-confusable at both levels,
    whatever its tracks say, so that enrolling fewer recordings never asks for fewer signatures."""
    from signatures.train.separability import MIN_SEPARABLE_CLAIMS, single_confusable, track_confusable

    assert MIN_SEPARABLE_CLAIMS == 29 and 1 - 0.9 ** 29 >= 0.95 > 1 - 0.9 ** 28
    clean_tracks = {"false_accept_rate": 0.0, "false_accepts": 0, "claims": 800, "dwells": 8}
    for claims, confusable in ((10, True), (28, True), (29, False), (60, False)):
        pair = {"single_dwell": {"false_accept_rate": 0.0, "false_accepts": 0, "claims": claims},
                "tracks": clean_tracks}
        assert single_confusable(pair) is confusable
        assert track_confusable(pair) is confusable
    busy = {"single_dwell": {"false_accept_rate": 2 / 60, "false_accepts": 2, "claims": 60}, "tracks": clean_tracks}
    assert single_confusable(busy) is True and track_confusable(busy) is False


def test_track_errors_separate_a_pair_single_dwells_cannot() -> None:
    """Cross-validated dwell scores of a pair with 25 % single-dwell false accepts (weakly
    positive LLRs among negative ones) are accepted on no drawn 8-dwell track; the pair is then
    confusable for single-dwell checks and not for track checks. Too few dwells for a full track
    keep the single-dwell verdict; scores that keep accepting stay confusable over tracks."""
    from authn.track import Sprt
    from signatures.train.separability import TRACK_DWELLS, _pair_tracks, track_confusable, track_rates

    impostor = [(0.5, True)] * 5 + [(-1.5, True)] * 15
    sd = {"false_accept_rate": 0.25, "false_accepts": 10, "claims": 40}
    t = _pair_tracks({("a", "b"): impostor, ("b", "a"): impostor}, "a", "b", Sprt(), seed=0)
    assert t["false_accept_rate"] == 0.0 and t["dwells"] == TRACK_DWELLS and t["claims"] > 0
    assert track_confusable({"single_dwell": sd, "tracks": t}) is False
    short = _pair_tracks({("a", "b"): impostor[:6], ("b", "a"): impostor[:6]}, "a", "b", Sprt(), seed=0)
    assert short["dwells"] == 6 and track_confusable({"single_dwell": sd, "tracks": short}) is True
    strong = [(3.0, True)] * 18 + [(-1.0, True)] * 2
    assert track_rates(strong, Sprt().walk)[0] > 0.9
    t = _pair_tracks({("a", "b"): strong, ("b", "a"): strong}, "a", "b", Sprt(), seed=0)
    assert track_confusable({"single_dwell": sd, "tracks": t}) is True
    # no physics term: a dwell only counts against the claim, as in authn check --track
    assert track_rates([(3.0, False)] * 20, Sprt().walk)[0] == 0.0


def test_sprt_walk_matches_the_track_policy() -> None:
    """Sprt.walk decides as the default policy's track rules do on decide_track's request."""
    from authn.track import Sprt

    sprt = Sprt()
    assert sprt.walk([(4.0, True), (4.0, True)])[0] == "inconclusive"  # 8 / 1.2 = 6.67 < 6.9
    assert sprt.walk([(4.0, True)] * 3) == ("accept", 3)  # 12 / 1.4 = 8.6
    assert sprt.walk([(-4.0, True), (-4.0, True)]) == ("reject", 2)
    assert sprt.walk([]) == ("inconclusive", 0)


@pytest.mark.parametrize("context,decision,reasons", [
    # radar-confusable-unsigned is an inconclusive forbid: even a track past the accept bound
    # cannot vouch for an unsigned claim of a confusable model, but it does not refute it either
    (dict(radar_confusable=True), "inconclusive", ["radar-confusable-unsigned"]),
    # ... while radar evidence that refutes the claim, or another forbid, still rejects it
    (dict(radar_confusable=True, track=sprt_record(-500)), "reject",
     ["radar-claim-inconsistent", "radar-confusable-unsigned"]),
    (dict(radar_confusable=True, range_residual_cm=2000), "reject", ["radar-confusable-unsigned", "range-mismatch"]),
    (dict(radar_confusable=True, remote_id_auth="valid"), "accept", ["registered-active"]),
    # a valid signature needs only radar that favours the claim
    (dict(radar_confusable=True, remote_id_auth="valid", track=sprt_record(100)), "accept", ["registered-active"]),
    (dict(radar_confusable=False), "accept", ["registered-active"]),
    ({}, "accept", ["registered-active"]),  # not a site bundle: the request is unchanged
])
def test_policy_rows(context: dict, decision: str, reasons: list[str]) -> None:
    """The site-enrolment forbid against the default policy (GOOD's track is past the accept bound)."""
    result = PolicyEngine.load().decide("S1", ACTIVE, SITE, {**GOOD, **context})
    assert (result.decision, result.reasons, result.errors) == (decision, reasons, [])


@pytest.mark.parametrize("labels,expected", [
    ("file,model\nm300-00.h5,m300\n", "no label in"),  # the other recordings are unlabelled
    ("file,model\nm300-00.h5,x9\n", "unknown model 'x9'"),
    ("name,kind\n", "header must be exactly 'file,model'"),
    ("file,model\n../escape.h5,m300\n", "outside the CSV's folder"),
    ("file,model\nmissing.h5,m300\n", "does not exist"),
    ("file,model\nm300-00.h5,M 300\n", "labels.csv:2: model"),
])
def test_bad_labels_are_one_line_and_change_nothing(site: dict, tmp_path: Path, capsys, labels: str,
                                                    expected: str) -> None:
    before = _active()
    folder = tmp_path / "flights"
    folder.mkdir()
    for f in site["flights"].glob("*.h5"):
        (folder / f.name).symlink_to(f)
    if "x9" in labels:  # every recording labelled, one with a model nobody registered
        rows = [f"{f.name},{f.name.split('-')[0]}" for f in sorted(folder.glob("*.h5")) if f.name != "m300-00.h5"]
        labels = labels + "\n".join(rows) + "\n"
    (folder / "labels.csv").write_text(labels)
    capsys.readouterr()
    assert main(["models", "enrol", str(folder), "--labels", str(folder / "labels.csv"), *BASE]) == 2
    assert expected in _one_line_error(capsys)
    assert _active() == before


def test_too_few_recordings_and_another_waveform(site: dict, tmp_path: Path, capsys) -> None:
    capsys.readouterr()
    few = sorted(site["flights"].glob("m300-*.h5"))[:3] + sorted(site["flights"].glob("m600-*.h5"))
    (tmp_path / "labels.csv").write_text("file,model\n" + "".join(f"{f.name},{f.name.split('-')[0]}\n" for f in few))
    for f in few:
        (tmp_path / f.name).symlink_to(f)
    assert main(["models", "enrol", str(tmp_path), "--labels", str(tmp_path / "labels.csv"), *BASE]) == 2
    assert "model m300: 3 recordings, at least 5 per model needed" in _one_line_error(capsys)
    wide = tmp_path / "wide.h5"
    assert main(["simulate", "--preset", "wide", "--model", "m300", "--range", "300", "--out", str(wide)]) == 0
    (tmp_path / "labels.csv").write_text("file,model\n" + "".join(f"{f.name},{f.name.split('-')[0]}\n" for f in few)
                                         + "wide.h5,m300\n")
    capsys.readouterr()
    assert main(["models", "enrol", str(tmp_path), "--labels", str(tmp_path / "labels.csv"), *BASE]) == 2
    assert "recordings are of 2 waveforms" in _one_line_error(capsys)


def test_copies_of_one_flight_are_one_recording(site: dict, tmp_path: Path, capsys) -> None:
    """15 copies of one m300 flight (other names, same bytes) are one recording: refused as one
    file would be, saying how many were ignored; the same bytes under two labels are bad input."""
    before = _active()
    one = sorted(site["flights"].glob("m300-*.h5"))[0]
    rows = ["file,model"]
    for i in range(15):
        (tmp_path / f"copy-{i:02d}.h5").write_bytes(one.read_bytes())
        rows.append(f"copy-{i:02d}.h5,m300")
    for f in sorted(site["flights"].glob("m600-*.h5")) + sorted(site["flights"].glob("phantom4-*.h5")):
        (tmp_path / f.name).symlink_to(f)
        rows.append(f"{f.name},{f.name.split('-')[0]}")
    (tmp_path / "labels.csv").write_text("\n".join(rows) + "\n")
    capsys.readouterr()
    assert main(["models", "enrol", str(tmp_path), "--labels", str(tmp_path / "labels.csv"), *BASE]) == 2
    assert ("model m300: 1 recording, at least 5 per model needed (14 duplicate recordings ignored)"
            in _one_line_error(capsys))
    (tmp_path / "labels.csv").write_text("\n".join(rows).replace("copy-07.h5,m300", "copy-07.h5,m600") + "\n")
    assert main(["models", "enrol", str(tmp_path), "--labels", str(tmp_path / "labels.csv"), *BASE]) == 2
    assert "copy-07.h5 are the same recording" in _one_line_error(capsys) and _active() == before


def test_interrupted_enrolment_leaves_the_previous_bundle_active(site: dict, capsys, monkeypatch) -> None:
    before = _active()
    assert before

    def crash(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr("signatures.classify.modelcard.write_card", crash)
    flights = site["flights"]
    try:  # SIGINT half way: typer turns KeyboardInterrupt into exit 130
        rc = main(["models", "enrol", str(flights), "--labels", str(flights / "labels.csv"), "--name", "site-b", *BASE])
    except (KeyboardInterrupt, SystemExit) as exc:
        rc = getattr(exc, "code", 130)
    assert rc != 0
    assert _active() == before
    assert not (site["models"] / "site-b").exists()
    assert not [p for p in site["models"].iterdir() if p.name.startswith(".enrol-")]


def test_add_extends_the_active_enrolment(site: dict, tmp_path: Path, capsys) -> None:
    more = tmp_path / "more"
    _make_site(more, 2, seed=99)
    (more / "again.h5").write_bytes((site["flights"] / "m300-00.h5").read_bytes())  # enrolled already
    (more / "copy.h5").write_bytes((more / "m600-00.h5").read_bytes())  # a copy of a new one
    with (more / "labels.csv").open("a") as fh:
        fh.write("again.h5,m300\ncopy.h5,m600\n")
    capsys.readouterr()
    assert main(["models", "enrol", str(more), "--labels", str(more / "labels.csv"), "--add", "--name", "site-c",
                 "--site-bands", "on", "--calibrate", "on", "--json", *BASE]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["counts"] == {"m300": 7, "m600": 7, "phantom4": 7} and doc["duplicates_ignored"] == 2
    card = json.loads((site["models"] / "site-c" / "card.json").read_text())
    assert card["enrolment"]["previous"] == "site-a" and list(_active().values()) == ["site-c"]
    bands = card["enrolment"]["bands"]  # --site-bands: each model's bands from its recordings, today's the prior
    assert set(bands) == {"m300", "m600", "phantom4"} and all(0 < b["rate"][0] < b["rate"][1] for b in bands.values())
    from signatures.classify.inference import load_classifier
    from signatures.classify.verify import bands_from

    assert bands_from(load_classifier(path=site["models"] / "site-c").physics_bands, "m300") is not None
    from signatures.classify.calibration import calibration_of  # --calibrate: the check verifies with it

    assert card["enrolment"]["calibration"]["applied"] is True and doc["calibration"]["applied"] is True
    assert calibration_of(load_classifier(path=site["models"] / "site-c")) is not None
    assert calibration_of(load_classifier(path=site["models"] / "site-a")) is None
    capsys.readouterr()
    main(["check", str(more / "phantom4-00.h5"), "--json"])  # phantom4 registered above
    v = json.loads(capsys.readouterr().out)["radar"]["verification"]
    assert "uncalibrated" in v and "offset" in v["terms"]
    assert abs(v["llr"] - sum(v["terms"].values())) < 1e-3
