"""`benchmarks/batch_stages.py`: the stage timers account for the batch's time and leave the
batch path as they found it; the transforms-alone table has the preset's transforms; bad
arguments exit 2 (docs/benchmarks.md, "Batch mode")."""

from __future__ import annotations

import pytest

from signatures.dsp import flash_period
from signatures.dsp import extraction as bf


@pytest.fixture(scope="module")
def bs(benchmark_script):
    return benchmark_script("batch_stages")


def test_stages_add_up_and_the_batch_path_is_restored(bs):
    before = {name: getattr(mod, name) for mod, name in bs.STAGES}
    ms, faults = bs.stages("paper", 8, 1)
    assert faults >= 0.0
    assert {name for _, name in bs.STAGES} <= ms.keys()
    assert all(v >= 0.0 for k, v in ms.items() if k != "rest of the slow stage")
    top = ms["_cube_stage"] + ms["_subchirp_bins"] + ms["_slow_stage"] + ms["classifier"]
    assert top <= ms["total"] * 1.0001  # the top-level stages run one after another inside the total
    inner = ms["flash_series_batch"] + ms["periodicity_batch"] + ms["_spectrogram"] + ms["_cadence"]
    assert ms["rest of the slow stage"] == pytest.approx(ms["_slow_stage"] - inner)
    assert {name: getattr(mod, name) for mod, name in bs.STAGES} == before
    assert bf._cube_stage is before["_cube_stage"] and flash_period.periodicity_batch is before["periodicity_batch"]


@pytest.mark.parametrize("preset,sub", [("paper", True), ("wide", False)])
def test_transforms_alone_are_the_presets(bs, preset, sub):
    ms = bs.transforms(preset, 4, 1)
    assert ("sub-chirp products" in ms) == sub  # `wide` has no sub-chirp windows
    assert {"cube passes + range FFT", "Doppler FFT", "STFT"} <= ms.keys()
    assert ms["total"] == pytest.approx(sum(v for k, v in ms.items() if k != "total"))
    assert all(v > 0.0 for v in ms.values())


@pytest.mark.parametrize("argv", [["--batch", "0"], ["--rounds", "0"], ["--preset", "cw"]])
def test_bad_arguments_exit_2(bs, argv, capsys):
    with pytest.raises(SystemExit) as exc:
        bs.main(argv)
    assert exc.value.code == 2
    assert "error:" in capsys.readouterr().err
