"""`authn check --plot DIR`: one evidence figure per recorded decision, of a fixed size, with
the range-Doppler map, the spectrogram and the flash-rate panel, the verdict in its title.

A single check is a track of one dwell (Wald's sequential test): at the default targets one
unsigned dwell reaches neither bound, so the genuine M300 and the Phantom 4 claiming it are
`inconclusive` (exit 4) and only the moved Remote ID (range-mismatch) is rejected; at the looser
targets (--false-accept 0.02 --false-reject 0.02) the radar refutes the Phantom 4 on one dwell."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from authn.cli import main

pytest.importorskip("matplotlib", reason="the plot extra (matplotlib) is not installed")

M300 = "1581BDEM00000002"


@pytest.fixture(scope="module")
def world(tmp_path_factory) -> dict:
    from authn.demo import register_examples

    root = tmp_path_factory.mktemp("figure")
    db = f"sqlite:///{root / 'r.sqlite3'}"
    register_examples(db)
    files = {}
    for name, model, extra in (("genuine", "m300", []), ("type", "phantom4", []), ("moved", "m300", ["--rid-offset",
                                                                                                    "300"])):
        files[name] = root / f"{name}.h5"
        assert main(["simulate", "--model", model, "--range", "400", "--speed", "3", "--rid-serial", M300,
                     "--out", str(files[name]), *extra]) == 0
    return {"db": db, "root": root, "files": files}


def test_one_figure_per_decision_with_its_panels(world: dict, capsys) -> None:
    import matplotlib.image as mpimg

    from authn import figure

    out = world["root"] / "figs"
    files = world["files"]
    code = main(["--db", world["db"], "check", str(files["genuine"]), str(files["type"]), str(files["moved"]),
                 "--plot", str(out)])
    assert code == 1  # the worst of: one rejection (moved), two inconclusive (4 ranks below 1)
    err = capsys.readouterr().err
    written = sorted(p.name for p in out.iterdir())
    assert [re.sub(r"-audit\d+", "", n) for n in written] == ["genuine.png", "moved.png", "type.png"]
    assert err.count("wrote ") == 3
    height, width = mpimg.imread(next(out.glob("type-audit*.png"))).shape[:2]
    assert (width, height) == (round(figure.SIZE_IN[0] * figure.DPI), round(figure.SIZE_IN[1] * figure.DPI))


def test_the_figure_shows_the_evidence(world: dict, monkeypatch, tmp_path: Path, capsys) -> None:
    """The panels, axes and marks as drawn (read back from matplotlib, not from pixels)."""
    import json

    import matplotlib.pyplot as plt

    from authn import figure
    from signatures.recording import read_recording

    def drawn(*extra: str, code: int):
        seen = {}
        monkeypatch.setattr(plt, "close", lambda fig: seen.setdefault("fig", fig))
        capsys.readouterr()
        assert main(["--db", world["db"], "check", str(world["files"]["type"]), "--json", *extra]) == code
        doc = json.loads(capsys.readouterr().out)
        figure.draw(read_recording(world["files"]["type"]), doc, tmp_path / "t.png")
        return seen["fig"]

    fig = drawn(code=4)  # the defaults: one dwell is inconclusive
    rd, spectrogram, cadence, plain = [a for a in fig.axes if a.get_title()]
    assert plain.get_title() == "Claimed vs measured"
    assert [t.get_text() for t in plain.get_yticklabels()] == ["flash rate", "rotors", "range", "velocity"]
    words = [t.get_text() for t in plain.texts]
    assert any(w.startswith("claimed 80 Hz, measured") for w in words), words
    assert len(words) == 4 and "registered band" in [t.get_text() for t in plain.get_legend().get_texts()]
    band = [p for p in cadence.patches if abs(p.get_alpha() or 1.0) > 0.4 and p.get_facecolor()[:3] != (1, 1, 1)]
    assert band, "the claimed band on the cadence panel is drawn solid, not a faint white stripe"
    assert rd.get_xlabel() == "range (m)" and "radial velocity" in rd.get_ylabel()
    assert spectrogram.get_xlabel() == "time (ms)" and cadence.get_xlabel() == "cadence frequency (Hz)"
    labels = [t.get_text() for t in cadence.get_legend().get_texts()]
    assert any(t.startswith("claimed 80 Hz") for t in labels) and any(t.startswith("measured") for t in labels)
    assert [t.get_text() for t in rd.get_legend().get_texts()] == ["radar: phantom4", "Remote ID"]
    title = fig._suptitle
    assert "INCONCLUSIVE" in title.get_text() and "radar-inconclusive" in title.get_text()
    assert title.get_color() == "darkorange"
    title = drawn("--false-accept", "0.02", "--false-reject", "0.02", code=1)._suptitle  # refuted on one dwell
    assert "REJECT" in title.get_text() and "radar-claim-inconsistent" in title.get_text()
    assert title.get_color() == "firebrick"



def test_plot_never_overwrites_an_earlier_decisions_figure(world: dict, capsys) -> None:
    """The same file checked twice into one folder: two figures, one per decision (its audit id
    in the name), the first left as it was."""
    out = world["root"] / "twice"
    args = ["--db", world["db"], "check", str(world["files"]["type"]), "--plot", str(out), "--json"]
    main(args)
    first_id = json.loads(capsys.readouterr().out)["audit_id"]
    first = out / f"type-audit{first_id}.png"
    before = first.read_bytes()
    main(args)
    second_id = json.loads(capsys.readouterr().out)["audit_id"]
    assert second_id != first_id
    assert sorted(p.name for p in out.iterdir()) == sorted([first.name, f"type-audit{second_id}.png"])
    assert first.read_bytes() == before
