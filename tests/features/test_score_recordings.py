"""`authn features score`: the estimators scored on recordings against a truth file (lab/recordings.py),
with the simulated conditions' own rule, and a truth file that is not valid refused in one line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from authn.cli import main
from lab.accuracy import CONDITIONS, Estimate, Truth, evaluate_condition, render_condition, score
from lab.recordings import read_truth, score_recordings
from signatures.recording import write_recording
from tests.lab_plugin import needs_lab

HEADER = "file,rotor_rate_hz,radial_velocity_mps,rotors,note\n"


@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> tuple[Path, list[float]]:
    """Three seeded dwells of `cw-hover-tagged` written as an `authn import` directory, and their
    true mechanical rotor rates."""
    root = tmp_path_factory.mktemp("recorded")
    rates = []
    for i in range(3):
        rec, _, rate, _, _ = render_condition(CONDITIONS["cw-hover-tagged"], "training", i)
        write_recording(rec, root / "capture" / f"dwell_{i:06d}.h5")
        rates.append(rate)
    return root, rates


def test_recordings_score_as_the_simulated_condition_does(recorded) -> None:
    """The same three scenes, read back from files with one truth row each, give the condition's row."""
    root, rates = recorded
    (root / "truth.csv").write_text(HEADER + "".join(f"capture/dwell_{i:06d}.h5,{r!r},0,4,\n"
                                                     for i, r in enumerate(rates)))
    per_row, dwells = score_recordings(read_truth(root / "truth.csv"))
    want = evaluate_condition("cw-hover-tagged", n=3, seed=0)
    got = per_row[-1][1]
    assert per_row[-1][0] == "all" and got.n == 3 and len(dwells) == 3
    assert (got.velocity_ok, got.rotor_ok, got.rotors_ok, got.at_double, got.at_half) == (
        want.velocity_ok, want.rotor_ok, want.rotors_ok, want.at_double, want.at_half)
    assert got.rotor_median_err == pytest.approx(want.rotor_median_err)


def test_a_directory_shares_its_row_and_a_wrong_truth_shows_as_a_slip(recorded) -> None:
    """A directory row scores each of its dwells against the row's truth; a truth at twice the rates
    read shows every dwell 'at 0.5x truth' and none right, and an empty cell is not scored."""
    root, _ = recorded
    estimates = [Estimate(True, 150.0, 0.2, 4.0), Estimate(True, 151.0, -0.4, 3.0), Estimate(True, 149.0, 2.5, 6.0)]
    it = iter(estimates)
    (root / "slip.csv").write_text(HEADER + "capture,300,,4,\n")
    (name, s), = score_recordings(read_truth(root / "slip.csv"), estimate=lambda rec: next(it))[0]
    assert (name, s.n, s.rotor_ok, s.at_half, s.at_double) == ("capture", 3, 0.0, 1.0, 0.0)
    assert s.velocity_ok is None and s.rotors_ok == pytest.approx(2 / 3)


def test_scores_count_only_the_dwells_that_have_each_truth() -> None:
    right = Estimate(True, 100.0, 0.0, 4.0)
    s = score([(right, Truth(100.0, None, None)), (right, Truth(None, 5.0, None)), (Estimate(False, 0, 0, 0), Truth())])
    assert (s.n, s.detected, s.rotor_ok, s.velocity_ok, s.rotors_ok) == (3, pytest.approx(2 / 3), 1.0, 0.0, None)
    with pytest.raises(ValueError):
        score([])


@needs_lab
def test_the_command_prints_a_table_and_json(recorded, capsys) -> None:
    root, rates = recorded
    (root / "cli.csv").write_text(HEADER + f"capture/,{sum(rates) / 3},0,4,mean of the three\n")
    assert main(["features", "score", str(root / "cli.csv")]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].startswith("| file | dwells |") and lines[2].startswith("| capture/ | 3 | 100% |")
    assert main(["features", "score", str(root / "cli.csv"), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [r["file"] for r in doc["rows"]] == ["capture/"] and len(doc["dwells"]) == 3
    assert doc["dwells"][0]["file"].endswith("dwell_000000.h5") and doc["rows"][0]["velocity_ok"] == 1.0


@needs_lab
@pytest.mark.parametrize(("text", "message"), [
    ("file,rate\ncapture,1\n", "columns file, rotor_rate_hz"),
    ("rotor_rate_hz\n150\n", "file required"),
    (HEADER, "no rows"),
    (HEADER + ",150,,,\n", "the file cell is empty"),
    (HEADER + "capture,fast,,,\n", "rotor_rate_hz 'fast' is not a number"),
    (HEADER + "capture,nan,,,\n", "not a finite number"),
    (HEADER + "capture,9000,,,\n", "outside 1-2000 Hz"),
    (HEADER + "capture,,500,,\n", "exceeds +-200 m/s"),
    (HEADER + "capture,,,4.5,\n", "not a whole number"),
    (HEADER + "capture,,,,just a note\n", "no truth to score"),
    (HEADER + "missing.h5,150,,,\n", "no such file or directory"),
    (HEADER + "empty,150,,,\n", "no .h5/.hdf5/.npz recordings"),
    (HEADER + "capture,150,0,4,note,extra\n", "more cells than the header"),
])
def test_a_bad_truth_file_is_refused_in_one_line(recorded, capsys, text: str, message: str) -> None:
    root, _ = recorded
    (root / "empty").mkdir(exist_ok=True)
    (root / "bad.csv").write_text(text)
    assert main(["features", "score", str(root / "bad.csv")]) == 2
    out = capsys.readouterr()
    err = out.err.strip().splitlines()
    assert not out.out and len(err) == 1 and message in err[0] and "bad.csv" in err[0], err


@needs_lab
def test_a_recording_the_reader_refuses_is_bad_input(recorded, capsys) -> None:
    root, _ = recorded
    (root / "junk.h5").write_bytes(b"not a recording")
    (root / "junk.csv").write_text(HEADER + "junk.h5,150,,,\n")
    assert main(["features", "score", str(root / "junk.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "junk.h5" in err[0]
