"""`authn plot`, `authn features show` and `authn features accuracy`."""

from __future__ import annotations

import json

from authn.cli import main
from signatures.recording import write_recording
from tests.features.conftest import sim
from tests.lab_plugin import needs_lab


def test_plot_writes_the_five_figures(tmp_path, capsys):
    files = []
    for seed in (1, 2):
        rec, _ = sim(seed=seed)
        files.append(str(write_recording(rec, tmp_path / f"r{seed}.h5")))
    assert main(["plot", *files, "--out", str(tmp_path / "png")]) == 0
    names = {p.name for p in (tmp_path / "png").iterdir()}
    assert names == {"rd_map.png", "spectrogram.png", "mean_spectrogram.png", "doppler_intensity.png",
                     "cadence_velocity.png"}
    assert all(p.stat().st_size > 5000 for p in (tmp_path / "png").iterdir())


@needs_lab
def test_features_show_and_accuracy_json(tmp_path, capsys):
    rec, _ = sim(model="m600")
    path = write_recording(rec, tmp_path / "m600.h5")
    assert main(["features", "show", str(path), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["detected"] and abs(doc["features"]["rotor_rate_hz"] - 36.7) < 1.9
    assert 6 * 0.7 <= doc["physics"]["rotors_seen"] <= 6 * 1.1
    assert main(["features", "accuracy", "--preset", "paper", "--snr", "10", "--n", "3", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert rows[0]["n"] == 3 and rows[0]["preset"] == "paper"


def test_bad_input_is_exit_2(tmp_path, capsys):
    assert main(["plot", str(tmp_path / "missing.h5"), "--out", str(tmp_path)]) == 2
    assert main(["features", "accuracy", "--snr", "x", "--n", "1"]) == 2
    assert main(["features", "accuracy", "--world", "reality", "--n", "1"]) == 2
    assert "error:" in capsys.readouterr().err
