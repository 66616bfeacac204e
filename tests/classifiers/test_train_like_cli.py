"""`authn models train --like` end to end: a 512-chirp recording no shipped classifier serves gets
its own bundle (user models folder), and `authn check` then decides it with that bundle.

A single check is a track of one dwell decided by Wald's sequential test: at the default targets
one unsigned dwell (capped at +-4 nats) crosses neither bound, so a genuine claim with no other
forbid is `inconclusive` (exit 4), which is what these checks show the user bundle deciding."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterator
from pathlib import Path

import pytest

from authn.cli import main, output
from authn.demo import register_examples
from signatures.classify.inference import bundle_dir
from signatures.radar import recording_waveform
from signatures.recording import read_recording
from tests.classifiers.conftest import own_models

M300 = "1581BDEM00000002"


@pytest.fixture(scope="module")
def world(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict]:
    """A registry, a 512-chirp genuine m300 flight, a paper flight; models and cache in temp folders."""
    root = tmp_path_factory.mktemp("like")
    with own_models(root):
        db = f"sqlite:///{root / 'r.sqlite3'}"
        register_examples(db)
        files = {}
        for name, extra in (("cut", ["--chirps", "512"]), ("paper", [])):
            files[name] = root / f"{name}.h5"
            assert main(["simulate", "--model", "m300", "--range", "500", "--speed", "3", "--snr", "20",
                         "--rid-serial", M300, "--seed", "4", "--out", str(files[name]), *extra]) == 0
        yield {"root": root, "db": db, **files}


def _err(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err and len(err.splitlines()) == 1, err
    return err


def test_no_bundle_names_the_command_that_builds_one(world: dict, capsys) -> None:
    capsys.readouterr()
    assert main(["--db", world["db"], "check", str(world["cut"]), "--serial", M300]) == 2
    assert (f"no classifier for this waveform (512x80 at 77 GHz, PRI 44 us): build one with "
            f"`authn models train --like {world['cut']}`") in _err(capsys)


def test_train_like_then_check_decides_with_the_user_bundle(world: dict, capsys, monkeypatch) -> None:
    wf = recording_waveform(read_recording(world["cut"]))
    capsys.readouterr()
    assert main(["models", "train", "--like", str(world["cut"]), "--samples", "150", "--val-samples", "50",
                 "--test-samples", "20"]) == 0
    out = capsys.readouterr().out
    assert "Simulating" in out and "held-out test, 20 returns per SNR" in out
    folder = world["root"] / "models" / wf.name
    card = json.loads((folder / "card.json").read_text())
    assert card["preset"] == wf.name and set(card["metrics"]["test"]["per_snr"]) == {"0", "10", "20"}
    assert "--test-samples 20" in card["training"]["command"]

    code = main(["--db", world["db"], "check", str(world["cut"]), "--serial", M300, "--json"])
    doc = json.loads(capsys.readouterr().out)
    # one unsigned dwell at the default targets: decided by the user bundle, inconclusive
    assert (code, doc["decision"], doc["reasons"]) == (4, "inconclusive", ["radar-inconclusive"])
    assert doc["to_decide"]["dwells"] == 1 and doc["radar"]["verification"]["llr"] is not None
    assert doc["model_card_sha256"] == hashlib.sha256((folder / "card.json").read_bytes()).hexdigest()
    assert doc["radar"] is not None and doc["radar"]["model"] is not None

    from authn.check import Checker

    outcome = Checker(world["db"]).evaluate(world["cut"], M300)
    assert outcome.evidence.preset == wf.name

    assert main(["--db", world["db"], "check", str(world["cut"]), "--serial", M300, "--model", str(folder)]) == 4
    assert main(["--db", world["db"], "check", str(world["paper"]), "--serial", M300, "--model", str(folder)]) == 2
    assert ("this bundle is for 512x80 at 77 GHz, PRI 44 us (carrier band +-2.5%), the file's waveform is 600x80"
            in _err(capsys))

    assert main(["models", "list"]) == 0
    rows = [line.split("\t") for line in capsys.readouterr().out.splitlines()]  # piped: tab-separated
    assert [wf.name, "user"] in [r[1:3] for r in rows] and ["paper", "shipped"] in [r[1:3] for r in rows]
    monkeypatch.setenv("COLUMNS", "80")
    monkeypatch.setattr(output, "is_terminal", lambda: True)
    assert main(["models", "list"]) == 0
    listing = capsys.readouterr().out
    assert wf.name in listing and "shipped" in listing and "…" not in listing
    assert max(len(line) for line in listing.splitlines()) <= 80


def test_shipped_bundles_are_never_overwritten_by_accident(world: dict, capsys, tmp_path: Path) -> None:
    shipped = bundle_dir("paper") / "card.json"
    before = shipped.read_bytes()
    for args, needle in (
        (["--preset", "paper", "--out", str(bundle_dir("paper"))], "inside the shipped bundles"),
        (["--like", str(world["cut"]), "--out", str(bundle_dir("paper").parent / "mine")], "inside the shipped"),
        (["--preset", "wide", "--out", str(bundle_dir("paper")), "--overwrite-shipped"], "inside the shipped"),
        (["--preset", "paper", "--overwrite-shipped"], "--overwrite-shipped: only with"),
        (["--like", str(world["paper"])], "shipped preset 'paper'"),
        (["--like", str(world["cut"]), "--preset", "paper"], "give only one of"),
    ):
        capsys.readouterr()
        assert main(["models", "train", *args, "--samples", "50"]) == 2, args
        assert needle in _err(capsys)
    assert shipped.read_bytes() == before and not (bundle_dir("paper").parent / "mine").exists()
    keep = tmp_path / "notes"
    keep.mkdir()
    (keep / "thesis.txt").write_text("precious")
    assert main(["models", "train", "--like", str(world["cut"]), "--out", str(keep), "--samples", "50"]) == 2
    assert "is not a model bundle" in _err(capsys) and (keep / "thesis.txt").read_text() == "precious"


def test_radar_config_of_another_domain_is_refused(world: dict, tmp_path: Path, capsys) -> None:
    wf = recording_waveform(read_recording(world["cut"]))
    cfg = tmp_path / "cw.json"
    cfg.write_text(json.dumps({**wf.as_json(), "domain": "cw"}))
    capsys.readouterr()
    assert main(["models", "train", "--radar-config", str(cfg), "--samples", "50"]) == 2
    assert "a CW waveform has exactly one sample per pulse" in _err(capsys)


def test_preset_training_defaults_to_the_user_folder(world: dict, capsys) -> None:
    """`--preset` without `--out` once replaced the shipped bundle; now it writes a user bundle, and
    paper files keep the shipped classifier unless `--model` names the new one."""
    shipped = bundle_dir("paper") / "card.json"
    before = shipped.read_bytes()
    assert main(["models", "train", "--preset", "paper", "--samples", "60", "--val-samples", "50"]) == 0
    assert "still serves paper files" in capsys.readouterr().out
    folder = world["root"] / "models" / "paper"
    card = json.loads((folder / "card.json").read_text())
    assert card["preset"] == "paper" and "waveform" not in card and "test" not in card["metrics"]
    assert shipped.read_bytes() == before
    main(["--db", world["db"], "check", str(world["paper"]), "--serial", M300, "--json"])
    assert json.loads(capsys.readouterr().out)["model_card_sha256"] == hashlib.sha256(before).hexdigest()
    main(["--db", world["db"], "check", str(world["paper"]), "--serial", M300, "--json", "--model", str(folder)])
    assert json.loads(capsys.readouterr().out)["model_card_sha256"] == hashlib.sha256(
        (folder / "card.json").read_bytes()).hexdigest()


def test_a_cw_recording_gets_its_own_bundle_and_decides_without_range(world: dict, capsys) -> None:
    """`simulate --domain cw` -> `models train --like` -> `check`: the CW bundle serves the file,
    the decision carries no radar range and says why."""
    cw = world["root"] / "cw.h5"
    assert main(["simulate", "--model", "m300", "--range", "500", "--snr", "20", "--domain", "cw",
                 "--seed", "5", "--out", str(cw)]) == 0
    rec = read_recording(cw)
    assert rec.domain == "cw" and rec.iq.shape == (600, 1)
    capsys.readouterr()
    assert main(["--db", world["db"], "check", str(cw), "--serial", M300]) == 2
    assert "build one with `authn models train --like" in _err(capsys)
    assert main(["models", "train", "--like", str(cw), "--samples", "150", "--val-samples", "50",
                 "--test-samples", "20"]) == 0
    capsys.readouterr()
    code = main(["--db", world["db"], "check", str(cw), "--serial", M300, "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert code in (0, 1) and doc["radar"]["range_m"] is None
    assert doc["radar"]["range_evidence"] == "not measured: CW recording"


def test_randomised_training_is_recorded_in_the_card(world: dict, tmp_path: Path, capsys) -> None:
    out = tmp_path / "rand"
    assert main(["models", "train", "--like", str(world["cut"]), "--randomise", "--samples", "60",
                 "--val-samples", "50", "--test-samples", "10", "--out", str(out)]) == 0
    card = json.loads((out / "card.json").read_text())
    assert card["training"]["dataset"]["randomisation"]["rotor_rate_scale"] == [0.85, 1.15]
    assert "--randomise" in card["training"]["command"]
